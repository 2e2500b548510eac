"""Luminance, lux, lamp spectra, efficacy and lamp colour."""

import colour
import numpy as np
import pytest
from scipy.integrate import trapezoid

from gevsim.errors import ConfigError
from gevsim.optics import (
    illuminance_lux,
    lamp_spectrum,
    luminance,
    luminous_efficacy_lm_per_w,
    spectrum_to_rgb,
)


def test_luminance_uses_rec709_weights():
    assert [float(luminance(row)) for row in np.eye(3)] == [0.2126, 0.7152, 0.0722]
    # a 2-D array is a mono image unless mono=False says it holds RGB triples
    np.testing.assert_array_equal(luminance(np.eye(3)), np.eye(3))
    np.testing.assert_allclose(luminance(np.eye(3), mono=False), [0.2126, 0.7152, 0.0722])
    img = np.ones((4, 5, 3))
    np.testing.assert_allclose(luminance(img), np.ones((4, 5)), rtol=1e-12)
    mono = np.arange(20.0).reshape(4, 5)
    np.testing.assert_array_equal(luminance(mono), mono)
    np.testing.assert_array_equal(luminance(mono[..., None]), mono)
    with pytest.raises(ValueError, match=r"shape \(4, 5, 2\)"):
        luminance(np.ones((4, 5, 2)))


def test_illuminance_is_683_times_y():
    assert illuminance_lux(1.0) == 683.0
    np.testing.assert_allclose(illuminance_lux(np.array([0.0, 2.0])), [0.0, 1366.0])


@pytest.mark.parametrize("lamp", ["A", "D65", "FL2", "FL11", "HP1", "LPS", "LED-B3", "Mercury"])
def test_spectrum_to_rgb_round_trips_luminance(lamp):
    rgb = spectrum_to_rgb(lamp, luminance_cd_m2=250.0)
    assert rgb.shape == (3,) and np.all(rgb >= 0)
    assert illuminance_lux(luminance(rgb)) == pytest.approx(250.0, rel=1e-12)


def test_d65_is_srgb_white_and_sodium_is_orange():
    rgb = spectrum_to_rgb("D65", luminance_cd_m2=683.0)
    np.testing.assert_allclose(rgb, 1.0, atol=2e-4)
    r, g, b = spectrum_to_rgb("HP1", luminance_cd_m2=683.0)
    assert r > 2 * g > 0 and b < 0.05 * g


def test_low_pressure_sodium_is_clipped_to_gamut():
    # LPS is nearly monochromatic (589 nm): outside sRGB, blue would be negative.
    rgb = spectrum_to_rgb("LPS", luminance_cd_m2=100.0)
    assert rgb[2] == 0.0
    assert luminance(rgb) * 683.0 == pytest.approx(100.0, rel=1e-12)


def test_lamp_spectrum_returns_copy_from_both_tables():
    sd = lamp_spectrum("FL11")
    sd.values = sd.values * 0
    assert colour.SDS_ILLUMINANTS["FL11"].values.max() > 0
    assert lamp_spectrum("HPS").wavelengths[0] == 380.0


def test_unknown_lamp_raises_config_error_with_suggestion():
    with pytest.raises(ConfigError, match=r"'FL 11'.*did you mean 'FL11'"):
        lamp_spectrum("FL 11")
    with pytest.raises(ConfigError, match=r"'sodium'.*'HP1'") as info:
        lamp_spectrum("sodium", source="scene.toml", key="lights.street.lamp")
    assert info.value.source == "scene.toml"


def test_equal_energy_efficacy_matches_direct_integral_and_colour():
    lef = colour.colorimetry.SDS_LEFS_PHOTOPIC["CIE 1924 Photopic Standard Observer"]
    expected = 683.0 * trapezoid(lef.values, lef.wavelengths) / (830.0 - 360.0)
    sd_e = colour.SDS_ILLUMINANTS["E"]  # flat, 360-830 nm
    assert luminous_efficacy_lm_per_w(sd_e) == pytest.approx(expected, rel=1e-4)
    assert luminous_efficacy_lm_per_w("E") == pytest.approx(colour.luminous_efficacy(sd_e), rel=1e-9)
    assert 150.0 < expected < 160.0


@pytest.mark.parametrize("lamp", ["A", "D65", "FL2", "HP1", "HPS", "LED-B3"])
def test_efficacy_agrees_with_colour(lamp):
    sd = lamp_spectrum(lamp)
    assert luminous_efficacy_lm_per_w(sd) == pytest.approx(colour.luminous_efficacy(sd), rel=1e-9)


def test_sodium_is_more_efficacious_than_incandescent():
    # HPS/LPS radiate near the V(lambda) peak; an incandescent lamp (A) in the red.
    a = luminous_efficacy_lm_per_w("A")
    hps = luminous_efficacy_lm_per_w("HP1")
    lps = luminous_efficacy_lm_per_w("LPS")
    assert hps > 2 * a
    assert lps > hps


def test_negative_luminance_rejected():
    with pytest.raises(ValueError, match="luminance_cd_m2"):
        spectrum_to_rgb("A", luminance_cd_m2=-1.0)
