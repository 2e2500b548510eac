"""APS frames: exact exposure integration, EMVA 1288 photon transfer, saturation, errors."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.constants import e as Q_E

from gevsim.errors import ConfigError
from gevsim.pixel.aps import ApsParams, ApsSensor, exposure_electrons, photon_transfer, system_gain_from_ptc

PERIOD = 0.01  # 100 Hz PWM: 1 pA over the first half of each period, 0 otherwise
I_ON = 1e-12


def pwm_current(n_periods=6, shape=(2, 3)):
    edges = np.arange(2 * n_periods + 1) * (PERIOD / 2)
    on = (np.arange(2 * n_periods) % 2 == 0) * I_ON
    scale = np.arange(1, shape[0] * shape[1] + 1, dtype=float).reshape(shape)  # per-pixel gain
    return on[:, None, None] * scale, edges, scale


def test_pwm_windows_of_different_phase_give_the_analytic_charge():
    current, edges, scale = pwm_current()
    # Quarter-period windows: on-overlap is P/4, 0, P/8, P/8, P/16 for these phases.
    starts = np.array([0.0, 0.5, 0.375, 0.875, 1.4375]) * PERIOD + PERIOD
    expected_on_s = np.array([0.25, 0.0, 0.125, 0.125, 0.0625]) * PERIOD
    got = exposure_electrons(current, edges, starts, PERIOD / 4)
    assert got.shape == (5, 2, 3) and got.dtype == np.float64
    np.testing.assert_allclose(got, expected_on_s[:, None, None] * I_ON * scale / Q_E, rtol=1e-12, atol=1e-9)


def test_whole_period_exposures_remove_flicker_short_ones_show_it():
    current, edges, scale = pwm_current()
    phases = np.linspace(0.0, 1.0, 17)[:-1] * PERIOD
    whole = exposure_electrons(current, edges, phases, 2 * PERIOD)
    mean_charge = I_ON / 2 * 2 * PERIOD * scale / Q_E  # duty 0.5: mean current I/2
    np.testing.assert_allclose(whole, np.broadcast_to(mean_charge, whole.shape), rtol=1e-12)
    short = exposure_electrons(current, edges, phases, PERIOD / 8)[:, 0, 0]
    assert short.max() == pytest.approx(I_ON * PERIOD / 8 / Q_E, rel=1e-12)
    assert short.min() == pytest.approx(0.0, abs=1e-9)
    # In DN (unsaturated) short exposures swing by K * max charge with phase; whole periods do not.
    params = ApsParams(full_well_e=1e5, system_gain_dn_per_e=0.02, bit_depth=12)
    sensor = ApsSensor((2, 3), params, rng=np.random.default_rng(0))
    dn_short = sensor.mean_dn(exposure_electrons(current, edges, phases, PERIOD / 8), PERIOD / 8)[:, 0, 0]
    assert np.ptp(dn_short) == pytest.approx(0.02 * I_ON * PERIOD / 8 / Q_E, rel=1e-9)
    dn_whole = sensor.mean_dn(exposure_electrons(current, edges, phases, PERIOD), PERIOD)[:, 0, 0]
    assert dn_whole.max() < params.max_dn and np.ptp(dn_whole) < 1e-9


def test_window_ending_on_the_last_edge_is_accepted():
    current, edges, scale = pwm_current(n_periods=2)
    got = exposure_electrons(current, edges, [0.0], edges[-1])
    np.testing.assert_allclose(got[0], I_ON * PERIOD * scale / Q_E, rtol=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.0, 1e-9), min_size=1, max_size=12),
       st.lists(st.floats(1e-4, 1e-2), min_size=13, max_size=13),
       st.floats(0.0, 1.0), st.floats(0.01, 1.0))
def test_exposure_matches_step_by_step_overlap_sum(levels, widths, start_frac, exp_frac):
    current = np.array(levels)[:, None, None]
    edges = np.concatenate([[0.25], 0.25 + np.cumsum(widths[: len(levels)])])
    span = edges[-1] - edges[0]
    exposure = exp_frac * span
    start = edges[0] + start_frac * (span - exposure)
    overlap = np.clip(np.minimum(edges[1:], start + exposure) - np.maximum(edges[:-1], start), 0.0, None)
    expected = float(np.sum(np.array(levels) * overlap)) / Q_E
    got = exposure_electrons(current, edges, start, exposure)[0, 0, 0]
    assert got == pytest.approx(expected, rel=1e-9, abs=1e-9 * max(levels) * span / Q_E + 1e-9)


def test_photon_transfer_slope_is_the_system_gain():
    k = 0.18
    params = ApsParams(full_well_e=20000.0, read_noise_e=8.0, dark_current_e_per_s=200.0, dsnu_e=30.0,
                       prnu=0.02, system_gain_dn_per_e=k, offset_dn=100.0, bit_depth=12)
    shape = (128, 128)
    sensor = ApsSensor(shape, params, rng=np.random.default_rng(1))
    levels = np.linspace(0.0, 0.7 * params.full_well_e, 8)
    electrons = np.broadcast_to(levels[:, None, None], (8,) + shape)
    a = sensor.read(electrons, 0.01, rng=np.random.default_rng(2))
    b = sensor.read(electrons, 0.01, rng=np.random.default_rng(3))
    mu, var = photon_transfer(a[1:], b[1:], dark_a=a[0], dark_b=b[0])
    assert mu.shape == (7,) and np.all(np.diff(mu) > 0)
    assert system_gain_from_ptc(mu, var) == pytest.approx(k, rel=0.05)
    # The dark pair's variance is read noise + dark shot noise + quantisation, in DN^2; the dark
    # electrons' Poisson mean is dark_current t + the DSNU offset, clipped at 0.
    _, var_dark = photon_transfer(a[0], b[0])
    dark_shot_e = np.clip(200.0 * 0.01 + sensor.dsnu_offset_e, 0.0, None).mean()
    expected_dark = k**2 * (params.read_noise_e**2 + dark_shot_e) + 1 / 12
    assert float(var_dark) == pytest.approx(expected_dark, rel=0.1)


def test_saturation_clips_at_full_well_code():
    params = ApsParams(full_well_e=10000.0, read_noise_e=0.0, dsnu_e=0.0, prnu=0.0,
                       system_gain_dn_per_e=0.2, offset_dn=50.0, bit_depth=12)
    sensor = ApsSensor((32, 32), params, rng=np.random.default_rng(4))
    frames = sensor.read(np.full((3, 32, 32), 5e4), 0.01, rng=np.random.default_rng(5))
    assert np.all(frames == round(0.2 * 10000.0 + 50.0))
    assert sensor.mean_dn(np.full((32, 32), 5e4), 0.01).max() == pytest.approx(2050.0)
    # With read noise the saturated code scatters around K * full_well + offset.
    noisy = ApsSensor((64, 64), replace(params, read_noise_e=10.0), rng=np.random.default_rng(4))
    frame = noisy.read(np.full((64, 64), 5e4), 0.01, rng=np.random.default_rng(6)).astype(float)
    assert frame.mean() == pytest.approx(2050.0, abs=0.1)
    assert frame.std() == pytest.approx(2.0, rel=0.1)


def test_saturation_clips_at_adc_range_with_float_output():
    params = ApsParams(bit_depth=8, system_gain_dn_per_e=0.05, full_well_e=20000.0)  # K FW + off > 255
    sensor = ApsSensor((16, 16), params, rng=np.random.default_rng(7))
    dn = sensor.read(np.full((16, 16), 1e6), 0.01, rng=np.random.default_rng(8))
    assert dn.dtype == np.uint16 and np.all(dn == 255)
    f = sensor.read(np.full((16, 16), 1e6), 0.01, rng=np.random.default_rng(8), output="float")
    assert f.dtype == np.float32 and np.all(f == 1.0)


def test_same_seeds_identical_frames_different_seeds_differ():
    electrons = np.full((2, 24, 32), 3000.0)
    def frames(sensor_seed, read_seed):
        sensor = ApsSensor((24, 32), ApsParams(), rng=np.random.default_rng(sensor_seed))
        return sensor.read(electrons, 0.02, rng=np.random.default_rng(read_seed))
    np.testing.assert_array_equal(frames(10, 20), frames(10, 20))
    assert not np.array_equal(frames(10, 20), frames(10, 21))
    assert not np.array_equal(frames(11, 20), frames(10, 20))


def test_dark_frames_mean_is_offset_plus_dark_signal():
    params = ApsParams(full_well_e=20000.0, read_noise_e=10.0, dark_current_e_per_s=5000.0, dsnu_e=20.0,
                       system_gain_dn_per_e=0.18, offset_dn=100.0, bit_depth=12)
    t_exp = 0.1
    sensor = ApsSensor((64, 64), params, rng=np.random.default_rng(9))
    frames = sensor.read(np.zeros((4, 64, 64)), t_exp, rng=np.random.default_rng(10)).astype(float)
    expected = 100.0 + 0.18 * 5000.0 * t_exp
    k = params.system_gain_dn_per_e
    per_pixel_sd = np.sqrt(k**2 * (5000.0 * t_exp + 10.0**2 + 20.0**2) + 1 / 12)
    assert abs(frames.mean() - expected) < 5 * per_pixel_sd / np.sqrt(64 * 64)
    assert sensor.mean_dn(np.zeros((64, 64)), t_exp)[0, 0] == pytest.approx(expected)
    # DSNU is fixed: the temporal mean keeps a spatial spread of about K dsnu.
    temporal_var = per_pixel_sd**2 - k**2 * 20.0**2
    assert frames.mean(axis=0).std() == pytest.approx(np.sqrt(k**2 * 20.0**2 + temporal_var / 4), rel=0.1)


def test_fill_factor_ratio_scales_the_photo_signal():
    params = ApsParams(dark_current_e_per_s=0.0, fill_factor_ratio=0.5, bit_depth=12,
                       system_gain_dn_per_e=0.1)
    sensor = ApsSensor((4, 4), params, rng=np.random.default_rng(0))
    dn = sensor.mean_dn(np.full((4, 4), 8000.0), 0.01)
    assert dn[0, 0] == pytest.approx(0.1 * 4000.0 + params.offset_dn)


@pytest.mark.parametrize("current, match", [(np.nan, "non-finite"), (-1e-12, "negative")])
def test_bad_current_is_named(current, match):
    photocurrent = np.full((2, 3, 3), 1e-12)
    photocurrent[1, 1, 1] = current
    with pytest.raises(ValueError, match=f"photocurrent_a has 1 {match}"):
        exposure_electrons(photocurrent, [0.0, 1.0, 2.0], [0.0], 0.5)


def test_bad_windows_and_edges_are_named():
    current = np.full((2, 3, 3), 1e-12)
    with pytest.raises(ValueError, match=r"window 1 .* outside .* time range"):
        exposure_electrons(current, [0.0, 1.0, 2.0], [0.0, 1.8], 0.5)
    with pytest.raises(ValueError, match="outside"):
        exposure_electrons(current, [0.0, 1.0, 2.0], [-0.1], 0.5)
    with pytest.raises(ValueError, match="t_edges_s must increase strictly"):
        exposure_electrons(current, [0.0, 1.0, 1.0], [0.0], 0.5)
    with pytest.raises(ValueError, match=r"shape \(T \+ 1,\)"):
        exposure_electrons(current, [0.0, 1.0], [0.0], 0.5)
    with pytest.raises(ValueError, match="exposure_s must be finite and > 0, got 0"):
        exposure_electrons(current, [0.0, 1.0, 2.0], [0.0], 0)
    sensor = ApsSensor((3, 3), ApsParams(), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"sensor shape \(3, 3\)"):
        sensor.read(np.ones((1, 4, 4)), 0.01, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="output must be"):
        sensor.read(np.ones((3, 3)), 0.01, rng=np.random.default_rng(0), output="raw")


def test_bad_params_are_named():
    with pytest.raises(ValueError, match=r"bit_depth must be an integer in 8\.\.16, got 40"):
        ApsParams(bit_depth=40)
    with pytest.raises(ValueError, match="prnu must be finite and >= 0, got -1"):
        ApsParams(prnu=-1)
    with pytest.raises(ValueError, match="system_gain_dn_per_e must be finite and > 0, got 0"):
        ApsParams(system_gain_dn_per_e=0)
    with pytest.raises(ConfigError, match=r"aps\.full_wel.*did you mean 'full_well_e'"):
        ApsParams.from_table({"full_wel": 100.0}, source="cam.toml")
    with pytest.raises(ConfigError, match=r"cam\.toml: aps\.bit_depth: bit_depth must be an integer in 8") as info:
        ApsParams.from_table({"bit_depth": 40}, source="cam.toml")
    assert info.value.key == "aps.bit_depth"
    assert ApsParams.from_table({"bit_depth": 12, "prnu": 0.005}) == ApsParams(bit_depth=12, prnu=0.005)
