"""The planar training scenes' textures and renderer: ranges, held-out photographs, determinism, and the
homography against its analytic image shift."""

import numpy as np
import pytest

from gevsim.errors import ConfigError
from gevsim.learn.planar import Trajectory, focal_px, render_planar, rotation
from gevsim.learn.textures import HELD_OUT, PHOTOS, PROCEDURAL, texture

W, H, FOV, DEPTH = 32, 24, 60.0, 2.0
FRONT = np.array([0.0, 0.0, -1.0])


def sliding(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The camera, unrotated, moving along x at 1 m/s."""
    centres = np.zeros((len(t), 3))
    centres[:, 0] = t
    return np.broadcast_to(np.eye(3), (len(t), 3, 3)), centres


@pytest.mark.parametrize("name", PHOTOS + HELD_OUT)
def test_photographs_are_gray_in_unit_range(name):
    tex = texture(name)
    assert tex.dtype == np.float64 and tex.ndim == 2 and min(tex.shape) >= 256
    assert 0.0 <= tex.min() < tex.max() <= 1.0


def test_held_out_photographs_never_train():
    assert not set(HELD_OUT) & set(PHOTOS)
    assert "cat" not in PHOTOS  # scikit-image's cat is chelsea


@pytest.mark.parametrize("kind", PROCEDURAL)
def test_procedural_textures_are_deterministic_per_seed(kind):
    a, b = (texture(kind, np.random.default_rng(5), size=64) for _ in range(2))
    other = texture(kind, np.random.default_rng(6), size=64)
    assert a.shape == (64, 64) and a.dtype == np.float64
    assert 0.0 <= a.min() < a.max() <= 1.0
    assert np.array_equal(a, b) and not np.array_equal(a, other)


def test_unknown_texture_names_suggestions():
    with pytest.raises(ConfigError, match="dead_leaves"):
        texture("dead_leaf", np.random.default_rng(0))


def test_translation_parallel_to_a_fronto_parallel_plane_shifts_by_f_t_over_depth():
    """On a ramp texture (bilinear and area averaging are exact on it) the image changes by slope x f t / depth."""
    f, slope, t = focal_px(W, FOV), 1e-3, 0.037
    ramp = np.tile(np.arange(300.0) * slope, (200, 1))
    frames = render_planar(ramp, width=W, height=H, fov_deg=FOV, t_s=np.array([0.0, t]), depth_m=DEPTH,
                           normal=FRONT, pose_at=sliding, texel_m=DEPTH / f, origin_px=(100.0, 80.0))
    assert f == pytest.approx(16.0 * np.sqrt(3.0), rel=1e-15)  # (W / 2) / tan(30 deg)
    assert 0.5 < f * t / DEPTH < 0.52  # a fraction of a pixel
    np.testing.assert_allclose(frames[1] - frames[0], slope * f * t / DEPTH, rtol=0, atol=1e-12)
    # and the first frame is the ramp itself: pixel centre x + 0.5 - W / 2 from the origin texel
    np.testing.assert_allclose(frames[0][0], slope * (100.0 + np.arange(W) + 0.5 - W / 2), rtol=0, atol=1e-12)


def test_a_whole_pixel_shift_moves_any_texture_exactly():
    f, k = focal_px(W, FOV), 3
    tex = texture("camera")
    frames = render_planar(tex, width=W, height=H, fov_deg=FOV, t_s=np.array([0.0, k * DEPTH / f]), depth_m=DEPTH,
                           normal=FRONT, pose_at=sliding, texel_m=DEPTH / f, origin_px=(200.0, 200.0))
    np.testing.assert_allclose(frames[1][:, :-k], frames[0][:, k:], rtol=0, atol=1e-12)
    assert not np.allclose(frames[1], frames[0])


def test_a_texture_finer_than_the_pixels_is_area_averaged():
    """A one-texel checkerboard four texels a pixel is uniform gray, not an alias."""
    board = (np.indices((256, 256)).sum(0) % 2).astype(np.float64)
    f = focal_px(W, FOV)
    frames = render_planar(board, width=W, height=H, fov_deg=FOV, t_s=np.array([0.0]), depth_m=DEPTH,
                           normal=np.array([0.1, 0.0, -1.0]), pose_at=sliding, texel_m=DEPTH / f / 4.0,
                           origin_px=(100.3, 90.7))
    assert np.abs(frames - 0.5).max() < 0.05


def test_trajectory_starts_at_the_origin_and_rotations_are_orthonormal():
    path = Trajectory((0.3, -0.1, 0.0), (0.01, 0.02, 0.1), (0.05, -0.05, 0.1), 0.4, 3.0, (0.1, 0.2, 0.3, 0.4, 0.5, 0.6))
    rot, centres = path(np.linspace(0.0, 0.2, 5))
    np.testing.assert_allclose(rot[0], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(centres[0], 0.0, atol=1e-15)
    product = (rot[:, :, :, None] * rot[:, :, None, :]).sum(1)  # R^T R
    np.testing.assert_allclose(product, np.broadcast_to(np.eye(3), product.shape), atol=1e-12)
    quarter = rotation(np.array([0.0, 0.5 * np.pi, 0.0]))  # about y: the optical axis turns to +x
    np.testing.assert_allclose(quarter[:, 2], [1.0, 0.0, 0.0], atol=1e-15)
