"""Camera equation, cos^4 falloff and lens validation."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim.optics import Lens, cos4_map, field_angle_map, focal_plane_irradiance, illuminance_lux


def test_uniform_radiance_on_axis_is_camera_equation():
    lens = Lens(f_number=2.8, transmission=0.85)
    radiance = np.full((48, 64), 3.7)
    e = focal_plane_irradiance(radiance, lens=lens)
    expected = 3.7 * 0.85 * math.pi / (4 * 2.8**2)
    np.testing.assert_allclose(e, expected, rtol=1e-15)
    assert lens.irradiance_factor == pytest.approx(0.85 * math.pi / (4 * 2.8**2), rel=1e-15)


def test_centre_pixel_of_odd_image_has_no_falloff():
    c4 = cos4_map(65, 49, fov_x_deg=70.0)
    assert c4[24, 32] == 1.0
    e = focal_plane_irradiance(np.ones((49, 65)), lens=Lens(), cos4=c4)
    assert e[24, 32] == pytest.approx(Lens().irradiance_factor, rel=1e-15)
    assert e.max() == e[24, 32]


def test_corner_falloff_of_90_degree_image():
    # 2x2 pixels, fov 90 deg: f = 1 px, corner centres at (0.5, 0.5) px,
    # tan^2(theta) = 0.5, so cos^4(theta) = (1 / 1.5)^2 = 4/9.
    np.testing.assert_allclose(cos4_map(2, 2, fov_x_deg=90.0), 4.0 / 9.0, rtol=1e-14)
    theta = field_angle_map(2, 2, fov_x_deg=90.0)
    np.testing.assert_allclose(theta, math.atan(math.sqrt(0.5)), rtol=1e-14)


def test_horizontal_edge_of_90_degree_image_approaches_45_degrees():
    theta = field_angle_map(1000, 1, fov_x_deg=90.0)
    assert theta[0, -1] == pytest.approx(math.atan(499.5 / 500.0), rel=1e-14)
    assert cos4_map(1000, 1, fov_x_deg=90.0)[0, -1] == pytest.approx(0.25, rel=5e-3)


def test_cos4_broadcasts_over_channels_and_stacks():
    lens = Lens(f_number=2.0, transmission=1.0)
    c4 = cos4_map(8, 6, fov_x_deg=60.0)
    rgb = np.ones((6, 8, 3), dtype=np.float32)
    e = focal_plane_irradiance(rgb, lens=lens, cos4=c4)
    assert e.dtype == np.float32 and e.shape == (6, 8, 3)
    np.testing.assert_allclose(e[..., 1], c4 * math.pi / 16, rtol=1e-6)
    stack = np.ones((4, 6, 8))
    np.testing.assert_allclose(focal_plane_irradiance(stack, lens=lens, cos4=c4)[2], c4 * math.pi / 16)
    with pytest.raises(ValueError, match="cos4 map shape"):
        focal_plane_irradiance(np.ones((5, 5)), lens=lens, cos4=c4)


def test_lux_example_1000_nit_scene_at_f2():
    # A Lambertian scene of 1000 cd/m^2, f/2, T = 1: E_v = 1000 pi / 16 = 196.3 lux.
    lens = Lens(f_number=2.0, transmission=1.0)
    radiance_y = np.full((4, 4), 1000.0 / 683.0)
    lux = illuminance_lux(focal_plane_irradiance(radiance_y, lens=lens))
    np.testing.assert_allclose(lux, 1000.0 * math.pi / 16.0, rtol=1e-14)
    assert lux[0, 0] == pytest.approx(196.35, abs=0.01)


def test_negative_and_nan_radiance_are_rejected_with_count():
    radiance = np.ones((4, 4))
    radiance[0, :2] = -1.0
    with pytest.raises(ValueError, match=r"radiance has 2 negative"):
        focal_plane_irradiance(radiance, lens=Lens())
    radiance[0, :2] = np.nan
    with pytest.raises(ValueError, match=r"radiance has 2 non-finite"):
        focal_plane_irradiance(radiance, lens=Lens())


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"f_number": 0.0}, "f_number"),
        ({"f_number": -1.4}, "f_number"),
        ({"transmission": 0.0}, "transmission"),
        ({"transmission": 1.2}, "transmission"),
        ({"focal_length_m": -0.01}, "focal_length_m"),
    ],
)
def test_bad_lens_parameters_name_the_field(kwargs, name):
    with pytest.raises(ValueError, match=name):
        Lens(**kwargs)


def test_lens_field_of_view():
    lens = Lens(focal_length_m=5e-3)
    # width * pitch = 2 f gives a 90 degree field of view
    assert lens.fov_x_deg(1000, pitch_m=10e-6) == pytest.approx(90.0, rel=1e-12)


@settings(max_examples=50, deadline=None)
@given(
    width=st.integers(1, 40),
    height=st.integers(1, 40),
    fov=st.floats(1.0, 170.0),
)
def test_field_angle_map_is_symmetric_and_bounded(width, height, fov):
    theta = field_angle_map(width, height, fov_x_deg=fov)
    assert theta.shape == (height, width)
    np.testing.assert_allclose(theta, theta[::-1, :], atol=1e-12)
    np.testing.assert_allclose(theta, theta[:, ::-1], atol=1e-12)
    half_diag = math.atan(math.hypot(1.0, height / width) * math.tan(math.radians(fov) / 2))
    assert np.all(theta >= 0) and np.all(theta < half_diag)
