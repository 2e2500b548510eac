"""Light-group basis rendering: linearity, caching, pose blending, radiometry."""

from pathlib import Path

import numpy as np
import pytest
from conftest import small, use_variant

from gevsim.optics import Lens, focal_plane_irradiance, illuminance_lux, luminance
from gevsim.render import MitsubaScene, render_basis
from gevsim.render.basis import cache_key
from gevsim.render.output import irradiance_frames

PANEL = Path(__file__).parents[1] / "data" / "panel.toml"


@pytest.mark.parametrize("scene, t_s", [("office", 0.0), ("street_night", 0.02), (PANEL, 0.0)])
def test_basis_images_sum_to_the_full_render(variant, scene, t_s):
    """Light transport is linear in emitter radiance: sum_k B_k = all lights on (same seed)."""
    sc = MitsubaScene(small(scene), variant=variant)
    sc.set_pose(sc.pose_at(t_s))
    sc.set_groups(None)
    full = sc.render().astype(np.float64)
    parts = []
    for name in sc.manifest.group_names:
        sc.set_groups({name})
        parts.append(sc.render().astype(np.float64))
    total = np.sum(parts, axis=0)
    assert full.max() > 0
    assert np.abs(total - full).max() <= 1e-4 * full.max()
    # Each group contributes: none of them is silently off.
    assert all(p.sum() > 0 for p in parts)


def test_directly_viewed_emitter_has_the_stated_luminance(variant):
    """683 * Y of a pixel seeing the panel equals its luminance (1000 cd/m^2), and the
    camera equation gives its focal-plane illuminance."""
    sc = MitsubaScene(small(PANEL), variant=variant)
    sc.set_pose(sc.pose_at(0.0))
    sc.set_groups({"panel"})
    img = sc.render()
    y = luminance(img[..., :3])
    top = 683.0 * y[:8]  # top rows see only the panel
    np.testing.assert_allclose(top, 1000.0, rtol=1e-4)
    e = focal_plane_irradiance(img, lens=Lens(f_number=2.0, transmission=1.0))
    np.testing.assert_allclose(illuminance_lux(luminance(e[..., :3]))[:8], 1000.0 * np.pi / 16, rtol=1e-4)


def test_second_run_renders_nothing(variant, tmp_path):
    sc = MitsubaScene(small("tabletop", duration_s=0.004), variant=variant)
    first = render_basis(sc, cache_dir=tmp_path)
    assert (first.render_s > 0).all()
    second = render_basis(sc, cache_dir=tmp_path)
    assert (second.render_s == 0).all()
    assert np.array_equal(first.images, second.images) and np.array_equal(first.noise, second.noise)
    assert len(list(tmp_path.glob("*.exr"))) == first.images.shape[0]  # one file per pose, every group in it
    assert second.quality == first.quality


def test_cache_key_depends_on_what_changes_the_render_not_on_quality(variant):
    a = MitsubaScene(small(PANEL), variant=variant)
    b = MitsubaScene(small(PANEL, spp=8), variant=variant)
    c = MitsubaScene(small(PANEL, seed=99), variant=variant)
    d = MitsubaScene(small(PANEL, sampler="ldsampler"), variant=variant)
    pose = a.pose_at(0.0)
    assert cache_key(a, pose) == cache_key(b, pose)  # quality is recorded in the file, not the name
    assert len({cache_key(s, pose) for s in (a, c, d)}) == 3
    assert cache_key(a, pose) == cache_key(MitsubaScene(small(PANEL), variant=variant), pose)


def test_cache_serves_better_renders_and_replaces_worse_or_corrupt_ones(variant, tmp_path):
    eight = render_basis(MitsubaScene(small(PANEL, spp=8), variant=variant), cache_dir=tmp_path)
    four = render_basis(MitsubaScene(small(PANEL, spp=4), variant=variant), cache_dir=tmp_path)
    assert (four.render_s == 0).all() and four.quality[0]["spp"] == 8  # the better image serves
    sixteen = render_basis(MitsubaScene(small(PANEL, spp=16), variant=variant), cache_dir=tmp_path)
    assert (sixteen.render_s > 0).all() and sixteen.quality[0]["spp"] == 16
    assert not np.array_equal(eight.images, sixteen.images)
    (path,) = tmp_path.glob("*.exr")
    path.write_bytes(b"not an exr")
    again = render_basis(MitsubaScene(small(PANEL, spp=4), variant=variant), cache_dir=tmp_path)
    assert (again.render_s > 0).all() and again.quality[0]["spp"] == 4


def test_pan_poses_keep_motion_under_one_pixel(variant):
    from gevsim.render.trajectory import project

    m = small("office_pan")
    sc = MitsubaScene(m, variant=variant)
    times = sc.pose_times()
    assert len(times) > 2 and times[0] == 0.0 and times[-1] == pytest.approx(m.duration_s)
    w, h = m.render.width, m.render.height
    pts = sc._probe[None]
    tracks = np.array([project(pts, sc.pose_at(t).camera, fov_deg=m.fov_deg, width=w, height=h) for t in times])
    visible = np.all(np.abs(tracks - [w / 2, h / 2]) < [w, h], axis=(0, 2))
    steps = np.linalg.norm(np.diff(tracks[:, visible], axis=0), axis=2)
    assert visible.sum() > 10
    assert steps.max() <= 1.05 * m.render.max_px_per_pose
    assert steps.max() >= 0.5 * m.render.max_px_per_pose  # and not wastefully many poses


def test_static_scene_has_one_pose(variant):
    assert len(MitsubaScene(small("office"), variant=variant).pose_times()) == 1


def test_projection_matches_mitsuba(variant):
    """A small bright sphere lands on the pixel the pinhole projection predicts."""
    m = small(PANEL, width=64, height=48)
    sc = MitsubaScene(m, variant=variant)
    sc.set_groups({"lamp"})
    img = luminance(sc.render(spp=16)[..., :3])
    v, u = np.argwhere(img > 0.9 * img.max()).mean(axis=0)  # centroid of the directly seen sphere
    from gevsim.render.trajectory import project

    pu, pv = project(np.array([[1.0, 0.0, 0.0]]), sc.pose_at(0.0).camera, fov_deg=m.fov_deg, width=64, height=48)[0]
    assert abs(u + 0.5 - pu) <= 1.0 and abs(v + 0.5 - pv) <= 1.0


def test_irradiance_follows_the_waveforms(variant, tmp_path):
    """E(t) = sum_k w_k(t) B_k: with the PWM panel off, only the lamp is left; the
    counterfactual (flicker off) run is the mean of the waveforms."""
    m = small(PANEL)
    basis = render_basis(MitsubaScene(m, variant=variant), cache_dir=tmp_path)
    lens = Lens(f_number=2.0, transmission=1.0)
    # PWM 1 kHz, duty 0.25: on for t in [0, 0.25 ms), off at 0.5 ms.
    on, off = irradiance_frames(basis, m, [0.0001, 0.0005], lens=lens)
    k_panel = basis.groups.index("panel")
    assert np.all(off <= on)
    # Off phase: the panel group contributes nothing.
    lamp_e = irradiance_frames(basis, m, [0.0005], lens=lens)[0]
    k_lamp = basis.groups.index("lamp")
    from gevsim.optics import cos4_map

    cos4 = cos4_map(64, 48, fov_x_deg=m.fov_deg)
    expected_lamp = focal_plane_irradiance(basis.images[0, k_lamp], lens=lens, cos4=cos4)
    np.testing.assert_allclose(lamp_e, expected_lamp, rtol=1e-5, atol=1e-12)
    # On phase: panel at 1/duty = 4 times its mean.
    expected_on = expected_lamp + 4.0 * focal_plane_irradiance(basis.images[0, k_panel], lens=lens, cos4=cos4)
    np.testing.assert_allclose(on, expected_on, rtol=1e-5, atol=1e-12)
    mean = irradiance_frames(basis, m, [0.0003], lens=lens, flicker=False)[0]
    np.testing.assert_allclose(mean, expected_lamp + focal_plane_irradiance(basis.images[0, k_panel], lens=lens,
                                                                            cos4=cos4), rtol=1e-5, atol=1e-12)


@pytest.mark.parametrize("name", ["scalar_mono", "scalar_spectral", "llvm_ad_mono", "llvm_ad_spectral",
                                  "cuda_ad_mono", "cuda_ad_spectral"])
def test_linearity_and_luminance_in_other_flavours(name):
    """Mono and spectral variants: basis sum = full render, and a directly seen
    emitter keeps its stated luminance (spectral: within Mitsuba's RGB upsampling error).
    PyPI's Mitsuba has no scalar_mono: that case is skipped (gevsim then renders RGB, see test_backend)."""
    flavour = name.rsplit("_", 1)[1]
    sc = MitsubaScene(small(PANEL, flavour=flavour), variant=use_variant(name))
    assert sc.variant.variant == name
    sc.set_groups(None)
    full = sc.render().astype(np.float64)
    total = 0.0
    for name in sc.manifest.group_names:
        sc.set_groups({name})
        total = total + sc.render().astype(np.float64)
    assert np.abs(total - full).max() <= 1e-4 * full.max()
    sc.set_groups({"panel"})
    img = sc.render()
    y = img[..., 0] if img.shape[-1] == 1 else luminance(img)
    # Spectral renders sample wavelengths per path: pixels scatter by a few
    # per cent at 4 spp, their mean does not.
    assert 683.0 * y[:8].mean() == pytest.approx(1000.0, rel=1e-2)
    if flavour == "mono":
        np.testing.assert_allclose(683.0 * y[:8], 1000.0, rtol=1e-4)
