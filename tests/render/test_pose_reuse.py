"""Reuse of converged radiance across poses: the rays of a pinhole grid, exact box resampling, and a
rotating camera's resampled poses against a render per pose."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from gevsim.errors import ConfigError
from gevsim.render import integrator, load, poses, rays, rotation
from gevsim.render.basis import render_basis
from gevsim.render.scene import MitsubaScene

SCENES = Path(__file__).parents[2] / "scenes"


def pan(width=32, height=24, **render) -> MitsubaScene:
    m = load(SCENES / "office_pan.toml")
    r = dataclasses.replace(m.render, width=width, height=height, noise_target_ln=None, **render)
    return MitsubaScene(dataclasses.replace(m, render=r))


def test_the_sensors_own_grid_gives_the_sensors_rays():
    scene = pan()
    pose = scene.pose_at(0.01)
    scene.set_pose(pose)
    film = scene.render_groups(spp=4, seed=5)
    grid = rays.sensor_grid(pose.camera, fov_deg=scene.manifest.fov_deg, width=32, height=24)
    ours = integrator.render_groups(scene.scene, scene._group_emitters, spp=4, seed=5,
                                    max_depth=scene.manifest.render.max_depth, grid=grid)
    # Same samples, same rays up to float32 rounding of the ray set-up (measured: 6e-6 relative at most).
    np.testing.assert_allclose(ours, film, rtol=1e-4, atol=1e-4 * film.max())


def test_box_resampling_is_the_exact_mean_of_the_cells_it_covers():
    rng = np.random.default_rng(0)
    cells = rng.random((2, 12, 15, 3))
    # Whole cells: block means.
    rect = np.stack(np.broadcast_arrays(3.0, 6.0, 6.0, 9.0))[:, None, None]
    np.testing.assert_allclose(rotation.box_resample(cells, rect)[:, 0, 0], cells[:, 6:9, 3:6].mean(axis=(1, 2)),
                               rtol=1e-6)
    # Fractional edges: against a fine numerical integral of the piecewise-constant image.
    x0, y0, x1, y1 = 2.3, 4.6, 5.45, 7.9
    fine = 400
    xs = x0 + (np.arange(fine) + 0.5) * (x1 - x0) / fine
    ys = y0 + (np.arange(fine) + 0.5) * (y1 - y0) / fine
    expected = cells[:, ys.astype(int)][:, :, xs.astype(int)].mean(axis=(1, 2))
    rect = np.array([x0, y0, x1, y1])[:, None, None]
    np.testing.assert_allclose(rotation.box_resample(cells, rect)[:, 0, 0], expected, rtol=2e-3)
    # A tiling of the image by rectangles conserves the integral.
    edges_x, edges_y = np.linspace(0, 15, 8), np.linspace(0, 12, 6)
    gx0, gy0 = np.meshgrid(edges_x[:-1], edges_y[:-1])
    gx1, gy1 = np.meshgrid(edges_x[1:], edges_y[1:])
    tiles = rotation.box_resample(cells, np.stack([gx0, gy0, gx1, gy1]))
    area = (gx1 - gx0) * (gy1 - gy0)
    np.testing.assert_allclose((tiles * area[None, ..., None]).sum(axis=(1, 2)), cells.sum(axis=(1, 2)), rtol=1e-5)
    # Squared weights: the variance of the mean of independent cells (9 whole cells of variance 1: 1/9;
    # a rectangle split 1:3 over two cells: (1/4)^2 + (3/4)^2).
    ones = np.ones((1, 12, 15, 1))
    rects = np.array([[3.0, 2.25], [6.0, 5.0], [6.0, 3.25], [9.0, 6.0]])[:, None, :]  # (4, 1, 2)
    np.testing.assert_allclose(rotation.box_resample(ones, rects, power=2)[0, 0, :, 0], [1 / 9, 0.625], rtol=1e-6)
    # A rectangle reaching past the grid takes the edge cell there.
    edge = rotation.box_resample(cells, np.array([-1.0, 0.0, 1.0, 1.0])[:, None, None])[:, 0, 0]
    np.testing.assert_allclose(edge, cells[:, 0, 0], rtol=1e-6)


def test_auto_reuse_takes_rotation_only_for_a_camera_turning_about_its_centre():
    scene = pan()
    assert poses.choose(scene, scene.pose_times()) == "rotation"
    tabletop = load(SCENES / "tabletop.toml")
    ball = MitsubaScene(dataclasses.replace(tabletop, render=dataclasses.replace(
        tabletop.render, width=32, height=24, reuse="rotation")))
    with pytest.raises(ConfigError, match="reuse = 'rotation' cannot render this scene: objects move") as err:
        poses.choose(ball, ball.pose_times())
    assert err.value.key == "render.reuse"


def test_resampled_poses_equal_a_render_per_pose_within_the_render_noise(tmp_path):
    """Same expectation: the difference of the two estimates over their combined standard error is a
    standard normal (mean 0, sd 1) pixel by pixel, and the reused basis is cached whole."""
    rotated = render_basis(pan(spp=64), cache_dir=tmp_path / "a")
    brute = render_basis(pan(spp=64, reuse="none"), cache_dir=tmp_path / "b")
    assert rotated.images.shape == brute.images.shape and len(rotated.times_s) > 4
    assert (rotated.render_s > 0).sum() == 1 and (brute.render_s > 0).all()
    from scipy.ndimage import uniform_filter

    var = uniform_filter(rotated.noise.astype(float) ** 2 + brute.noise.astype(float) ** 2, size=(1, 1, 5, 5, 1))
    z = (rotated.images - brute.images) / np.sqrt(var + 1e-30)
    assert abs(z.mean()) < 0.05 and 0.85 < z.std() < 1.2  # measured at 64x48: mean 0.0003, sd 1.04
    again = render_basis(pan(spp=64), cache_dir=tmp_path / "a")
    assert (again.render_s == 0).all()
    np.testing.assert_array_equal(again.images, rotated.images)
    assert again.quality[0]["reuse"] == "rotation"


def test_a_sliding_camera_reprojects_through_the_geometry_within_the_render_noise(tmp_path):
    """office_dolly (a static, diffuse room; the camera slides): auto picks parallax reuse, most pixels
    are reprojected, and the poses equal a render per pose in expectation."""
    m = load(SCENES / "office_dolly.toml")

    def dolly(**render):
        return MitsubaScene(dataclasses.replace(m, render=dataclasses.replace(
            m.render, width=32, height=24, noise_target_ln=None, spp=64, **render)))

    scene = dolly()
    assert poses.choose(scene, scene.pose_times()) == "parallax"
    moved = render_basis(scene, cache_dir=tmp_path / "a")
    brute = render_basis(dolly(reuse="none"), cache_dir=tmp_path / "b")
    reused = [q["reused_fraction"] for q in moved.quality]
    assert min(reused) > 0.6  # 32x24: edges are a large share of the pixels (measured 0.74-0.77)
    from scipy.ndimage import uniform_filter

    var = uniform_filter(moved.noise.astype(float) ** 2 + brute.noise.astype(float) ** 2, size=(1, 1, 5, 5, 1))
    z = (moved.images - brute.images) / np.sqrt(var + 1e-30)
    assert abs(z.mean()) < 0.05 and 0.85 < z.std() < 1.2  # measured at 64x48: mean -0.012, sd 1.07


def test_adaptive_parallax_meets_the_noise_target_at_every_pose(tmp_path):
    """sampling = "adaptive" (office_dolly's setting): the window and the cells rendered anew stop per pixel,
    every pose still meets the noise target at its percentile, and the poses equal uniform per-pose renders
    in expectation (z-scores of the difference over both noise samples)."""
    m = load(SCENES / "office_dolly.toml")
    assert m.render.sampling == "adaptive"

    def dolly(**render):
        return MitsubaScene(dataclasses.replace(m, render=dataclasses.replace(
            m.render, width=32, height=24, noise_target_ln=0.08, **render)))

    moved = render_basis(dolly(), cache_dir=tmp_path / "a")
    brute = render_basis(dolly(reuse="none", sampling="uniform"), cache_dir=tmp_path / "b")
    assert all(q["reuse"] == "parallax" and q["se_ln"]["p99"] <= 0.08 for q in moved.quality)
    assert any(q["spp_mean"] < q["spp"] for q in moved.quality)  # pixels did stop early
    from scipy.ndimage import uniform_filter

    var = uniform_filter(moved.noise.astype(float) ** 2 + brute.noise.astype(float) ** 2, size=(1, 1, 5, 5, 1))
    z = (moved.images - brute.images) / np.sqrt(var + 1e-30)
    assert abs(z.mean()) < 0.05 and 0.8 < z.std() < 1.25
