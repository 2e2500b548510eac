"""Silicon QE, responsivity, photocurrent and the optics config table."""

import math

import colour
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import constants

from gevsim.errors import ConfigError
from gevsim.optics import (
    SILICON_QE_FSI,
    Lens,
    Pixel,
    focal_plane_irradiance,
    from_spec,
    group_photocurrent_factors,
    photocurrent_a,
    photopic_lef,
    responsivity_a_per_lm,
    silicon_qe,
    silicon_qe_sd,
)


def _line(nm):
    return colour.SpectralDistribution({nm - 1: 0.0, nm: 1.0, nm + 1: 0.0}, name=f"{nm} nm")


def test_monochromatic_555_nm_with_unit_qe():
    expected = constants.e * 555e-9 / (constants.h * constants.c) / 683.0
    assert responsivity_a_per_lm(_line(555), qe=1.0) == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(6.554e-4, rel=1e-3)


def test_monochromatic_600_nm_divides_by_v_lambda():
    v600 = float(photopic_lef(600.0))
    assert v600 == pytest.approx(0.631, rel=1e-3)
    expected = constants.e * 600e-9 / (constants.h * constants.c) / (683.0 * v600)
    assert responsivity_a_per_lm(_line(600), qe=0.5) == pytest.approx(0.5 * expected, rel=1e-12)


def test_default_silicon_qe_shape():
    w = np.arange(300.0, 1201.0)
    qe = silicon_qe(w)
    peak = w[np.argmax(qe)]
    assert 500 <= peak <= 650 and 0.5 <= qe.max() <= 0.6
    assert silicon_qe(400.0) < 0.3
    assert silicon_qe(1100.0) == 0.0 and np.all(qe[w >= 1100] == 0)
    assert np.all(np.diff(qe[w >= 600]) <= 1e-12)
    np.testing.assert_allclose(silicon_qe(np.array(SILICON_QE_FSI[0])), SILICON_QE_FSI[1], atol=1e-12)
    assert silicon_qe_sd().wavelengths[-1] == 1100.0


def test_user_qe_table_and_bad_table():
    table = ([400.0, 500.0, 700.0], [0.1, 0.8, 0.2])
    assert silicon_qe(500.0, table=table) == pytest.approx(0.8)
    assert silicon_qe(800.0, table=table) == 0.0
    with pytest.raises(ValueError, match="qe has 1 value"):
        Pixel(qe=([400.0, 500.0], [0.2, 1.5]))
    with pytest.raises(ValueError, match="increase strictly"):
        silicon_qe(500.0, table=([500.0, 400.0], [0.2, 0.2]))


@pytest.mark.parametrize("lamp", ["A", "D65", "FL11", "HP1", "LED-B3"])
def test_default_qe_gives_less_current_than_ideal_detector(lamp):
    r = responsivity_a_per_lm(lamp)
    assert 0 < r < 0.6 * responsivity_a_per_lm(lamp, qe=1.0)


@settings(max_examples=25, deadline=None)
@given(scale=st.floats(1e-6, 1e6))
def test_responsivity_ignores_spectrum_scale(scale):
    sd = colour.SDS_ILLUMINANTS["FL2"]
    scaled = colour.SpectralDistribution(sd.values * scale, sd.wavelengths)
    assert responsivity_a_per_lm(scaled) == pytest.approx(responsivity_a_per_lm(sd), rel=1e-12)


def test_photocurrent_of_one_lux():
    pixel = Pixel(pitch_m=10e-6, fill_factor=0.5)
    i = photocurrent_a(np.full((2, 2), 1.0 / 683.0), pixel=pixel, responsivity_a_per_lm=1e-3)
    np.testing.assert_allclose(i, 1e-10 * 0.5 * 1e-3, rtol=1e-14)
    with pytest.raises(ValueError, match="irradiance_y has 1 negative"):
        photocurrent_a(np.array([1.0, -1.0]), pixel=pixel, responsivity_a_per_lm=1e-3)


def test_group_factors_match_lens_then_photocurrent():
    lens, pixel = Lens(f_number=1.4, transmission=0.9), Pixel()
    factors = group_photocurrent_factors({"street": "HP1", "office": "FL11"}, pixel=pixel, lens=lens)
    assert list(factors) == ["street", "office"]
    radiance_y = np.array([[0.5, 2.0]])
    for name, lamp in (("street", "HP1"), ("office", "FL11")):
        direct = photocurrent_a(
            focal_plane_irradiance(radiance_y, lens=lens),
            pixel=pixel,
            responsivity_a_per_lm=responsivity_a_per_lm(lamp),
        )
        np.testing.assert_allclose(factors[name] * radiance_y, direct, rtol=1e-13)
    arr = group_photocurrent_factors(["HP1", "FL11"], pixel=pixel, lens=lens)
    np.testing.assert_allclose(arr, [factors["street"], factors["office"]])
    expected = 0.9 * math.pi / (4 * 1.4**2) * 683 * pixel.area_m2 * responsivity_a_per_lm("HP1")
    assert arr[0] == pytest.approx(expected, rel=1e-13)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"pitch_m": -1e-6}, "pitch_m"),
        ({"fill_factor": 0.0}, "fill_factor"),
        ({"fill_factor": 1.5}, "fill_factor"),
    ],
)
def test_bad_pixel_parameters_name_the_field(kwargs, name):
    with pytest.raises(ValueError, match=name):
        Pixel(**kwargs)


def test_from_spec_builds_lens_and_pixel():
    lens, pixel = from_spec(
        {"f_number": 1.4, "transmission": 0.95, "focal_length_m": 0.012, "pitch_m": 9e-6,
         "fill_factor": 0.4, "qe": {"wavelength_nm": [400, 700], "qe": [0.3, 0.6]}}
    )
    assert lens == Lens(1.4, 0.95, 0.012)
    assert pixel.pitch_m == 9e-6 and pixel.fill_factor == 0.4
    assert pixel.qe_at(550.0) == pytest.approx(0.45)
    assert from_spec({}) == (Lens(), Pixel())


def test_from_spec_rejects_unknown_key_and_bad_value():
    with pytest.raises(ConfigError, match=r"cam\.toml: optics\.fill_facter.*did you mean 'fill_factor'"):
        from_spec({"fill_facter": 0.3}, source="cam.toml")
    with pytest.raises(ConfigError, match=r"optics\.f_number: f_number must be finite and > 0, got 0"):
        from_spec({"f_number": 0})
    with pytest.raises(ConfigError, match=r"optics\.pitch_m"):
        from_spec({"pitch_m": "9um"})
