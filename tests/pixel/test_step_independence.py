"""Answers that do not depend on the time step or on when the run starts (issue 22).

Every noise reaching the output passes two poles (gevsim.pixel._cascade), so its level
crossings are those of a differentiable path: counted on samples they converge as the step
shrinks (first order: the crossings missed between samples). Before, one-pole read and shot
noise gave gradient noise rates of 1,691 / 3,039 / 5,014 / 7,724 ev/px/s at 40 / 20 / 10 / 5 us
(sensor-physics audit, section 1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gevsim import _portable as pm
from gevsim.events import BrightnessEmulator, CenterSurroundEmulator, GradientEmulator
from gevsim.pixel import Photoreceptor, load_preset
from gevsim.pixel.noise import coarsest_step_s, shot_noise_variance_ln
from gevsim.pixel.params import EventParams
from gevsim.pixel.presets import lux_to_photocurrent_a, with_overrides

SHAPE = (24, 32)
DURATION_S, SKIP_S = 0.04, 0.005


def textured_lux(mean_lux: float) -> np.ndarray:
    """A static log-normal texture (sigma 0.5 ln) around ``mean_lux`` chip lux."""
    z = np.random.default_rng(7).standard_normal(SHAPE)
    return mean_lux * pm.exp(0.5 * z - 0.125)


def noise_rates(lux: np.ndarray, step_s: float) -> dict[str, float]:
    """Noise events per pixel per second of each emulator on a static scene, davis346 noise, DVS
    and CSDVS at 0.02 ln (the preset's 0.2 ln is 20 sigma away: leak only), after SKIP_S."""
    preset = load_preset("davis346")
    current = lux * lux_to_photocurrent_a(1.0, pixel_pitch_m=preset.pixel_pitch_m, fill_factor=preset.fill_factor)
    seeds = np.random.SeedSequence(3).spawn(5)
    pr = Photoreceptor(SHAPE, params=preset.photoreceptor, noise=preset.noise, rng=np.random.default_rng(seeds[0]))
    dvs = EventParams(threshold_on_ln=0.02, threshold_off_ln=0.02, threshold_mismatch_ln=0.002, refractory_s=1e-4,
                      reset_noise_ln=0.01)
    ems = {"dvs": BrightnessEmulator(SHAPE, dvs, rng=np.random.default_rng(seeds[1])),
           "gradient": GradientEmulator(SHAPE, mismatch_sigma_ln=0.005, rng=np.random.default_rng(seeds[2])),
           "gradient_rc": GradientEmulator(SHAPE, rc=True),
           "csdvs": CenterSurroundEmulator(SHAPE, dvs, rng=np.random.default_rng(seeds[3]))}
    n = int(round(DURATION_S / step_s))
    t_all = step_s * np.arange(1, n + 1)
    counts = dict.fromkeys(ems, 0)
    for a in range(0, n, 1000):
        t = t_all[a:a + 1000]
        v = pr.process(np.broadcast_to(current, (len(t),) + SHAPE), t)
        for name, em in ems.items():
            ev = em.process(v, t)
            counts[name] += int(np.count_nonzero(ev["t"] >= SKIP_S * 1e6))
    return {k: c / (SHAPE[0] * SHAPE[1] * (DURATION_S - SKIP_S)) for k, c in counts.items()}


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["uniform 10 lux", "textured 10 lux", "uniform 1000 lux"])
def test_noise_event_rates_do_not_depend_on_the_step(scene):
    lux = {"uniform 10 lux": np.full(SHAPE, 10.0), "textured 10 lux": textured_lux(10.0),
           "uniform 1000 lux": np.full(SHAPE, 1000.0)}[scene]
    preset = load_preset("davis346")
    brightest = float(lux.max()) * lux_to_photocurrent_a(1.0, pixel_pitch_m=preset.pixel_pitch_m,
                                                         fill_factor=preset.fill_factor)
    coarsest = min(20e-6, coarsest_step_s(preset.photoreceptor, preset.noise, brightest))  # what the driver takes
    by_step = {step: noise_rates(lux, step) for step in (coarsest, coarsest / 2, coarsest / 4)}
    for name in by_step[coarsest / 4]:
        rates = [r[name] for r in by_step.values()]
        if max(rates) < 2.0:  # too few events to compare (under ~70 in all)
            continue
        assert max(rates) / min(rates) < 1.10, f"{name}: {rates} ev/px/s at steps {list(by_step)} s"


def test_the_output_noise_is_the_two_pole_cascade():
    """Stationary variance of shot noise through the photoreceptor pole (alpha) and the output pole
    (beta): pi q f_c / I x beta / (alpha + beta); read noise: sigma^2 x beta / (alpha_r + beta)."""
    base = load_preset("davis346")
    preset = with_overrides(base, {"read_noise_v": 0.0, "feedback_shot_noise": False, "dc_offset_v": 0.0,
                                   "amplifier_noise_ln2_hz": 0.0})
    current = np.full((40, 50), 2e-12)
    pr = Photoreceptor(current.shape, params=preset.photoreceptor, noise=preset.noise, rng=np.random.default_rng(1))
    t = 2e-5 * np.arange(1, 4001)
    v = pr.process(np.broadcast_to(current, (len(t),) + current.shape), t).astype(np.float64)
    fc = float(preset.photoreceptor.cutoff_at(2e-12 + preset.noise.dark_current_a))
    alpha, beta = 2 * math.pi * fc, 2 * math.pi * preset.photoreceptor.second_pole_hz
    expected = float(shot_noise_variance_ln(2e-12 + preset.noise.dark_current_a, fc)) * beta / (alpha + beta)
    v = v - pr.steady_state(current)  # the noise (the fixed patterns' offsets removed)
    assert float(np.mean(v * v)) == pytest.approx(expected, rel=0.05)
    # and it starts stationary: the first samples already have that variance
    assert float(np.mean(v[0] * v[0])) == pytest.approx(expected, rel=0.15)


@pytest.mark.parametrize("cold", [False, True])
def test_a_periodic_light_starts_at_its_periodic_steady_state(cold):
    """settle(): after one period of the light, the noise-free state is where it started (the
    photoreceptor has been running), whatever the lamp phase; cold_start only changes the noise."""
    preset = with_overrides(load_preset("davis346"), {"shot_noise": False, "read_noise_v": 0.0,
                                                      "amplifier_noise_ln2_hz": 0.0})
    dt, n = 2e-5, 100  # a 2 ms period
    phase = np.arange(n) / n
    current = 1e-12 * (1.0 + 0.9 * pm.sin(2 * math.pi * phase))[:, None, None] * np.ones((1, 3, 4))
    pr = Photoreceptor((3, 4), params=preset.photoreceptor, noise=preset.noise, rng=np.random.default_rng(0),
                       cold_start=cold)
    pr.settle(current, np.full(n, dt))
    v1, v2 = pr.v1.copy(), pr.v2.copy()
    pr.process(np.concatenate([current, current]), dt * np.arange(1, 2 * n + 1))
    np.testing.assert_allclose(pr.v1, v1, rtol=0, atol=1e-9)
    np.testing.assert_allclose(pr.v2, v2, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="before the first process"):
        pr.settle(current, np.full(n, dt))


def test_without_a_photoreceptor_filter_the_output_pole_still_filters():
    """cutoff_hz = max_cutoff_hz = inf: the photoreceptor follows ln(I) at once and the output pole
    alone filters a step: y(t) = u2 - (u2 - u1) exp(-2 pi f_out t) (found by review: the pole was skipped)."""
    preset = with_overrides(load_preset("davis346"), {"cutoff_hz": math.inf, "max_cutoff_hz": math.inf,
                                                      "shot_noise": False, "read_noise_v": 0.0, "prnu": 0.0,
                                                      "dark_current_spread": 0.0, "dc_offset_v": 0.0,
                                                      "amplifier_noise_ln2_hz": 0.0})
    pr = Photoreceptor((1, 1), params=preset.photoreceptor, noise=preset.noise, rng=np.random.default_rng(0))
    dt = 2e-6
    t = dt * np.arange(1, 201)
    current = np.where(np.arange(200) < 1, 1e-12, 4e-12)[:, None, None]
    v = pr.process(current, t)[:, 0, 0].astype(np.float64)
    dark = preset.noise.dark_current_a
    u1, u2 = math.log(1e-12 + dark), math.log(4e-12 + dark)
    beta = 2 * math.pi * preset.photoreceptor.second_pole_hz
    expected = u2 - (u2 - u1) * np.exp(-beta * (t[1:] - t[0]))
    np.testing.assert_allclose(v[1:], expected, rtol=0, atol=2e-5)
