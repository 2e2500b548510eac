"""Flicker metrics against their analytic values (IEEE Std 1789-2015 definitions)."""

import math

import numpy as np
import pytest

from gevsim.illumination import (
    DC,
    PWM,
    Fluorescent,
    Incandescent,
    Sinusoid,
    SodiumHID,
    Table,
    Waveform,
    flicker_index,
    modulation_spectrum,
    percent_flicker,
)
from gevsim.illumination.mains import first_order_response


@pytest.mark.parametrize("duty", [0.05, 0.25, 0.5, 0.8])
def test_ideal_pwm(duty):
    w = PWM(300.0, duty, phase_s=1.7e-4)
    assert percent_flicker(w) == pytest.approx(100.0, abs=1e-3)
    assert flicker_index(w) == pytest.approx(1.0 - duty, abs=1e-3)


def test_pwm_dimmer_low_level():
    w = PWM(300.0, 0.5, low_level=0.25)  # levels 1 and 0.25
    assert percent_flicker(w) == pytest.approx(100 * 0.75 / 1.25)


def test_full_duty_pwm_is_steady():
    assert percent_flicker(PWM(100.0, 1.0)) == 0.0
    assert flicker_index(PWM(100.0, 1.0)) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("w", [Fluorescent(modulation=1.0), Sinusoid(120.0, modulation=1.0, phase_rad=0.4),
                               SodiumHID(reignition_fraction=0.0, persistence_s=0.0)])
def test_full_sin2_light(w):
    assert percent_flicker(w) == pytest.approx(100.0, abs=1e-6)
    assert flicker_index(w) == pytest.approx(1.0 / math.pi, abs=1e-5)


@pytest.mark.parametrize(("mains_hz", "tau"), [(50.0, 5e-3), (60.0, 1e-3), (50.0, 0.0)])
def test_fluorescent_percent_flicker_is_analytic_depth(mains_hz, tau):
    a, _ = first_order_response(mains_hz, tau)
    w = Fluorescent(mains_hz, persistence_s=tau)
    assert percent_flicker(w) == pytest.approx(100 * a, rel=1e-9)
    assert flicker_index(w) == pytest.approx(a / math.pi, abs=1e-6)


def test_default_lamps_have_typical_flicker():
    assert 25 < percent_flicker(Fluorescent()) < 35
    assert 5 < percent_flicker(Incandescent()) < 15
    assert percent_flicker(SodiumHID()) > 85
    assert percent_flicker(SodiumHID(60.0)) > 85
    assert flicker_index(SodiumHID()) == pytest.approx(0.3, abs=0.03)


def test_persistence_lowers_sodium_flicker():
    fast = SodiumHID(persistence_s=2e-4)
    slow = SodiumHID(persistence_s=2e-3)
    assert percent_flicker(slow) < percent_flicker(fast)
    assert flicker_index(slow) < flicker_index(fast)


def test_dc_has_no_flicker():
    assert percent_flicker(DC()) == 0.0
    assert flicker_index(DC()) == 0.0
    np.testing.assert_allclose(modulation_spectrum(DC(), harmonics=4), 0.0, atol=1e-12)


def test_table_metrics_over_its_span():
    w = Table([0.0, 1.0, 2.0], [0.0, 2.0, 0.0])  # triangle, mean 1
    assert percent_flicker(w) == pytest.approx(100.0)
    # area above mean 1: two triangles of base 0.5 and height 1 -> 0.5 of total 2
    assert flicker_index(w) == pytest.approx(0.25, abs=1e-6)


class _Square(Waveform):
    """A waveform without exact extrema: exercises the sampled path."""

    period_s = 0.01

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        return np.where(np.mod(t, 0.01) < 0.004, 2.0, 1.0 / 3.0)

    def cumulative(self, t):
        t = np.asarray(t, dtype=float)
        n, r = np.floor(t / 0.01), np.mod(t, 0.01)
        return n * 0.01 + np.where(r < 0.004, 2.0 * r, 0.008 + (r - 0.004) / 3.0)


def test_sampled_metrics_for_generic_waveform():
    w = _Square()
    assert w.value_range() is None and w.mean_value == pytest.approx(1.0)
    assert percent_flicker(w) == pytest.approx(100 * (2 - 1 / 3) / (2 + 1 / 3))
    assert flicker_index(w) == pytest.approx(0.4, abs=1e-4)


def test_modulation_spectrum_of_sinusoid_and_pwm():
    sin = modulation_spectrum(Sinusoid(50.0, 0.3, 1.0), harmonics=3)
    np.testing.assert_allclose(sin, [0.3, 0, 0], atol=1e-9)
    duty = 0.25
    n = np.arange(1, 6)
    # Fourier series of a mean-1 rectangular pulse train
    expected = 2 * np.abs(np.sin(np.pi * n * duty)) / (np.pi * n * duty)
    np.testing.assert_allclose(modulation_spectrum(PWM(100.0, duty), harmonics=5), expected, atol=1e-3)
    fl = modulation_spectrum(Fluorescent(), harmonics=2)
    assert fl[0] == pytest.approx(first_order_response(50.0, 5e-3)[0]) and fl[1] < 1e-9


def test_metrics_reject_bad_arguments():
    with pytest.raises(TypeError, match="not a Waveform"):
        flicker_index(np.ones(3))
    with pytest.raises(ValueError, match="harmonics must be a positive integer, got 0"):
        modulation_spectrum(DC(), harmonics=0)
    with pytest.raises(ValueError, match="samples must be an integer >= 2, got 1"):
        flicker_index(DC(), samples=1)
