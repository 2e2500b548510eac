"""Laws of the issue-23 mechanisms: temperature, feedback shot noise, DC-offset FPN, light leak, BSI QE."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.constants import elementary_charge

from gevsim.events import BrightnessEmulator
from gevsim.optics import SILICON_QE_BSI, SILICON_QE_FSI, responsivity_a_per_lm
from gevsim.pixel import Photoreceptor, load_preset
from gevsim.pixel.noise import dark_current_a
from gevsim.pixel.params import REFERENCE_TEMPERATURE_K, EventParams, NoiseParams, PhotoreceptorParams, thermal_factor


def test_thermal_factor_doubles_every_interval():
    assert thermal_factor(REFERENCE_TEMPERATURE_K, 7.0) == pytest.approx(1.0, rel=1e-15)
    assert thermal_factor(REFERENCE_TEMPERATURE_K + 7.0, 7.0) == pytest.approx(2.0, rel=1e-14)
    assert thermal_factor(REFERENCE_TEMPERATURE_K + 21.0, 7.0) == pytest.approx(8.0, rel=1e-14)
    assert thermal_factor(REFERENCE_TEMPERATURE_K - 7.0, 7.0) == pytest.approx(0.5, rel=1e-14)
    assert thermal_factor(350.0, math.inf) == 1.0


def test_dark_current_follows_temperature_in_the_photoreceptor():
    noise = NoiseParams(shot_noise=False, dark_current_a=4e-15, dark_current_spread=0.3, dark_current_doubling_k=7.0)
    warm = PhotoreceptorParams(temperature_k=REFERENCE_TEMPERATURE_K + 14.0)
    pr = Photoreceptor((64, 64), params=warm, noise=noise, rng=np.random.default_rng(1))
    ref = Photoreceptor((64, 64), params=PhotoreceptorParams(), noise=noise, rng=np.random.default_rng(1))
    assert dark_current_a(noise, warm.temperature_k) == pytest.approx(16e-15, rel=1e-12)
    np.testing.assert_allclose(pr.dark_a, 4.0 * ref.dark_a, rtol=1e-12)  # same pattern, 2^2 brighter


def test_feedback_transistor_doubles_the_shot_noise_variance():
    """Stationary output variance of shot noise through one pole: pi q f_c / I per source."""
    i = 1e-12
    params = PhotoreceptorParams(cutoff_hz=200.0, cutoff_ref_photocurrent_a=i, max_cutoff_hz=1e4)
    out = {}
    for fb in (False, True):
        noise = NoiseParams(shot_noise=True, dark_current_a=0.0, feedback_shot_noise=fb)
        pr = Photoreceptor((32, 32), params=params, noise=noise, rng=np.random.default_rng(3))
        t = 1e-4 * np.arange(1, 20001)
        v = pr.process(np.full((len(t), 32, 32), i), t)
        out[fb] = float(np.var(v[::20] - math.log(i)))  # samples 2 ms apart: ~independent (tau 0.8 ms)
    single = math.pi * elementary_charge * 200.0 / i
    assert out[False] == pytest.approx(single, rel=0.05)
    assert out[True] == pytest.approx(2.0 * single, rel=0.05)


def test_amplifier_noise_variance_is_inverse_to_the_cutoff():
    """The loop leaves the amplifier's noise an Ornstein-Uhlenbeck process on the photoreceptor pole:
    variance amplifier_noise_ln2_hz / f_c, so 10x less light (f_c ~ I) gives 10x the variance."""
    params = PhotoreceptorParams(cutoff_hz=100.0, cutoff_ref_photocurrent_a=1e-13, max_cutoff_hz=1e4)
    noise = NoiseParams(shot_noise=False, dark_current_a=0.0, amplifier_noise_ln2_hz=0.05)
    for i, fc in ((1e-13, 100.0), (1e-14, 10.0)):
        pr = Photoreceptor((32, 32), params=params, noise=noise, rng=np.random.default_rng(7))
        dt = 0.05 / fc  # samples 5 time constants apart are independent
        t = dt * np.arange(1, 4001)
        v = pr.process(np.full((len(t), 32, 32), i), t)
        assert float(np.var(v - math.log(i))) == pytest.approx(0.05 / fc, rel=0.05), fc


def test_dc_offsets_shift_the_output_but_not_the_dvs():
    """Offsets of sigma dc_offset_v / (n U_T) per pixel; a DVS is AC-coupled: its events are unchanged."""
    base = NoiseParams(shot_noise=True, read_noise_v=3e-4, dark_current_a=4e-15)
    params = PhotoreceptorParams(cutoff_hz=300.0, cutoff_ref_photocurrent_a=1e-13, second_pole_hz=2000.0)
    shape = (48, 48)
    t = 2e-5 * np.arange(1, 5001)
    cur = np.full((len(t),) + shape, 1e-14)
    outs, events = [], []
    for off in (0.0, 2e-3):
        pr = Photoreceptor(shape, params=params, noise=dataclasses.replace(base, dc_offset_v=off),
                           rng=np.random.default_rng(4))
        v = pr.process(cur, t)
        outs.append(v)
        dvs = BrightnessEmulator(shape, EventParams(threshold_on_ln=0.1, threshold_off_ln=0.1),
                                 rng=np.random.default_rng(5))
        events.append(dvs.process(v, t))
    shift = (outs[1] - outs[0])[0].astype(np.float64)
    assert np.std(shift) == pytest.approx(2e-3 / params.volts_per_ln, rel=0.05)
    np.testing.assert_allclose(outs[1] - outs[0], np.broadcast_to(shift, outs[0].shape), atol=1e-5)
    assert len(events[0]) > 100
    a, b = events
    assert len(a) == len(b)  # the same events; times may differ by the float32 rounding of the output (1 us)
    for f in ("x", "y", "p"):
        np.testing.assert_array_equal(np.sort(a[f]), np.sort(b[f]))
    assert np.max(np.abs(np.sort(a["t"]) - np.sort(b["t"]))) <= 1


def test_leak_grows_with_photocurrent_and_temperature():
    """Noise-free constant light: ON events at (leak_rate_hz * 2^(dT/dK) + leak_light_hz_per_a * I) per pixel."""
    shape = (32, 32)
    i = 2e-10
    t = 1e-3 * np.arange(1, 20001)  # 20 s
    v = np.full((len(t),) + shape, math.log(i), np.float32)
    for temp, light, expected in ((REFERENCE_TEMPERATURE_K, 0.0, 0.1), (REFERENCE_TEMPERATURE_K + 7.0, 0.0, 0.2),
                                  (REFERENCE_TEMPERATURE_K, 1e9, 0.1 + 0.2)):
        p = EventParams(leak_rate_hz=0.1, leak_doubling_k=7.0, leak_light_hz_per_a=light)
        dvs = BrightnessEmulator(shape, p, rng=np.random.default_rng(6), temperature_k=temp)
        ev = dvs.process(v, t)
        rate = len(ev) / (shape[0] * shape[1] * (t[-1] - t[0]))
        assert np.all(ev["p"])
        assert rate == pytest.approx(expected, rel=0.05), (temp, light)


def test_back_illuminated_silicon_collects_more_per_lumen():
    fsi = responsivity_a_per_lm("D65", qe=SILICON_QE_FSI)
    bsi = responsivity_a_per_lm("D65", qe=SILICON_QE_BSI)
    assert 1.2 < bsi / fsi < 1.8
    assert load_preset("imx636").quantum_efficiency == "bsi"
    assert load_preset("dvs128").fill_factor == 0.094  # L08's abstract
