"""Photoreceptor: step response, log response, shot noise, chunking, determinism, bad input; the
64-bit counter-based noise generator draws no repeated fields and ignores threads and chunking."""

import math

import numba
import numpy as np
import pytest
from numba import njit
from scipy import stats

from gevsim._finite import count_invalid
from gevsim.pixel import NoiseParams, Photoreceptor, PhotoreceptorParams, _kernels, shot_noise_variance_ln

QUIET = NoiseParams(shot_noise=False, dark_current_a=1e-18)
REC = PhotoreceptorParams(cutoff_hz=3000.0, cutoff_ref_photocurrent_a=1e-12, max_cutoff_hz=20000.0)
SHAPE = (4, 5)


def run(params, noise, current_steps, dt, *, seed=0, shape=SHAPE):
    """current_steps: (T,) photocurrents applied to every pixel, each held for dt."""
    pr = Photoreceptor(shape, params=params, noise=noise, rng=np.random.default_rng(seed))
    cur = np.broadcast_to(np.asarray(current_steps, float)[:, None, None], (len(current_steps),) + shape)
    return pr, pr.process(np.ascontiguousarray(cur), dt * np.arange(1, len(current_steps) + 1))


def measured_tau(out, u_start, u_end, dt, n_before):
    """Time for the response to cover 1 - 1/e of a step (linear interpolation between samples)."""
    x = (out[n_before - 1:, 0, 0].astype(float) - u_start) / (u_end - u_start)
    k = int(np.argmax(x >= 1 - math.exp(-1)))
    frac = (1 - math.exp(-1) - x[k - 1]) / (x[k] - x[k - 1])
    return (k - 1 + frac) * dt


@pytest.mark.parametrize("current_a", [1e-12, 1e-13])
def test_step_response_time_constant_matches_cutoff(current_a):
    tau = 1 / (2 * math.pi * REC.cutoff_at(current_a))
    dt = tau / 200
    n = 20
    steps = np.r_[np.full(n, current_a / 2), np.full(2000, current_a)]
    _, out = run(REC, QUIET, steps, dt)
    u0, u1 = math.log(current_a / 2 + 1e-18), math.log(current_a + 1e-18)
    assert measured_tau(out, u0, u1, dt, n) == pytest.approx(tau, rel=0.02)


def test_dimmer_is_slower_and_bandwidth_saturates():
    taus = []
    for current in (1e-14, 1e-13, 1e-12, 1e-9):
        tau = 1 / (2 * math.pi * REC.cutoff_at(current))
        steps = np.r_[np.full(5, current / 2), np.full(1500, current)]
        _, out = run(REC, QUIET, steps, tau / 100)
        taus.append(measured_tau(out, math.log(current / 2 + 1e-18), math.log(current + 1e-18), tau / 100, 5))
    assert taus[0] > taus[1] > taus[2] > taus[3]
    assert taus[3] == pytest.approx(1 / (2 * math.pi * 20000.0), rel=0.02)  # amplifier-limited


def test_tenfold_step_moves_settled_voltage_by_n_ut_ln10():
    pr, out = run(REC, QUIET, np.r_[np.full(100, 1e-12), np.full(3000, 1e-11)], 1e-5)
    volts = pr.to_volts(out[:, 0, 0].astype(float))
    assert volts[-1] - volts[99] == pytest.approx(REC.volts_per_ln * math.log(10), rel=1e-5)
    assert REC.volts_per_ln == pytest.approx(1.4 * 1.380649e-23 * 300 / 1.602176634e-19)


def test_second_pole_step_matches_the_analytic_two_pole_response():
    rec = PhotoreceptorParams(cutoff_hz=3000.0, cutoff_ref_photocurrent_a=1e-12, max_cutoff_hz=1e9,
                              second_pole_hz=1000.0)
    dt = 2e-6
    _, out = run(rec, QUIET, np.r_[np.full(1, 1e-12), np.full(2000, 2e-12)], dt)
    t = dt * np.arange(1, 2001)
    t1, t2 = 1 / (2 * math.pi * 6000.0), 1 / (2 * math.pi * 1000.0)
    e = math.log(1e-12 + 1e-18) - math.log(2e-12 + 1e-18)
    expect = math.log(2e-12 + 1e-18) + e * (t1 * np.exp(-t / t1) - t2 * np.exp(-t / t2)) / (t1 - t2)
    np.testing.assert_allclose(out[1:, 0, 0], expect, atol=2e-5)


def test_piecewise_constant_input_does_not_depend_on_dt():
    rng = np.random.default_rng(3)
    levels = 1e-12 * np.exp(rng.normal(0, 1, 50))
    _, coarse = run(REC, QUIET, levels, 2e-5)
    _, fine = run(REC, QUIET, np.repeat(levels, 8), 2.5e-6)
    np.testing.assert_allclose(fine[7::8], coarse, atol=2e-5)


@pytest.mark.parametrize("dt_over_tau", [0.2, 3.0])
def test_shot_noise_variance_matches_the_analytic_value(dt_over_tau):
    current = 1e-13
    fc = REC.cutoff_at(current + 1e-18)
    dt = dt_over_tau / (2 * math.pi * fc)
    noise = NoiseParams(shot_noise=True, dark_current_a=1e-18)
    _, out = run(REC, noise, np.full(4000, current), dt, shape=(16, 16))
    var = out[200:].astype(float).var(axis=0).mean()
    assert var == pytest.approx(float(shot_noise_variance_ln(current + 1e-18, fc)), rel=0.10)


@pytest.mark.parametrize("dt", [2e-6, 5e-5, 1e-3])
def test_read_and_flicker_noise_variances_do_not_depend_on_the_step(dt):
    noise = NoiseParams(shot_noise=False, dark_current_a=1e-18, read_noise_v=1e-3, flicker_noise_v=2e-3,
                        flicker_noise_low_hz=100.0, flicker_noise_high_hz=10000.0, read_noise_bandwidth_hz=2e4)
    # The noise states start in their stationary distribution and the mean is known
    # (ln of the current), so the mean square over pixels and time is unbiased.
    _, out = run(REC, noise, np.full(2000, 1e-12), dt, shape=(32, 32))
    var = np.mean((out.astype(float) - np.log(1e-12 + 1e-18)) ** 2)
    expect = (1e-3 / REC.volts_per_ln) ** 2 + (2e-3 / REC.volts_per_ln) ** 2
    assert var == pytest.approx(expect, rel=0.10)


FULL = NoiseParams(shot_noise=True, read_noise_v=1e-3, dark_current_a=3e-15, dark_current_spread=0.3, prnu=0.02,
                   flicker_noise_v=1e-3, flicker_noise_low_hz=10.0, flicker_noise_high_hz=1e4)


def _scene(rng, t_steps=120, shape=(6, 7)):
    return 1e-12 * np.exp(rng.normal(0, 1, (t_steps,) + shape))


def test_chunked_and_one_shot_runs_are_identical_bit_for_bit():
    rec = PhotoreceptorParams(second_pole_hz=5000.0)
    cur = _scene(np.random.default_rng(0))
    t = np.cumsum(np.random.default_rng(1).uniform(1e-6, 3e-5, len(cur)))
    one = Photoreceptor(cur.shape[1:], params=rec, noise=FULL, rng=np.random.default_rng(9)).process(cur, t)
    pr = Photoreceptor(cur.shape[1:], params=rec, noise=FULL, rng=np.random.default_rng(9))
    cuts = [0, 1, 17, 18, 60, 119, 120]
    parts = [pr.process(cur[a:b], t[a:b]) for a, b in zip(cuts, cuts[1:])]
    assert np.array_equal(one, np.concatenate(parts))


def test_same_seed_same_output_and_other_seed_differs():
    cur = _scene(np.random.default_rng(0))
    t = 1e-5 * np.arange(1, len(cur) + 1)
    a, b, c = (Photoreceptor(cur.shape[1:], params=REC, noise=FULL, rng=np.random.default_rng(s)).process(cur, t)
               for s in (5, 5, 6))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_fixed_pattern_noise_statistics():
    noise = NoiseParams(shot_noise=False, dark_current_a=1e-15, dark_current_spread=0.5, prnu=0.05)
    pr = Photoreceptor((200, 200), params=REC, noise=noise, rng=np.random.default_rng(2))
    assert pr.gain.std() == pytest.approx(0.05, rel=0.05) and pr.gain.mean() == pytest.approx(1.0, abs=2e-3)
    assert pr.dark_a.mean() == pytest.approx(1e-15, rel=0.02)  # lognormal with the stated mean
    assert np.log(pr.dark_a).std() == pytest.approx(0.5, rel=0.03)


def test_counter_based_normals_are_standard_normal():
    z = _kernels.normals(1234, 7, 2_000_000, 1)
    assert abs(z.mean()) < 5 / math.sqrt(len(z))
    assert z.var() == pytest.approx(1.0, abs=5e-3)
    assert abs(stats.kurtosis(z)) < 0.02
    assert stats.kstest(z, "norm").pvalue > 1e-3
    tail = np.mean(np.abs(z) > 4)
    assert tail == pytest.approx(2 * stats.norm.sf(4), rel=0.3)  # true tails, not truncated
    other = _kernels.normals(1234, 8, 100_000, 1)
    assert abs(np.corrcoef(z[:100_000], other)[0, 1]) < 0.02


def test_row_normals_equal_the_scalar_inversion_bit_for_bit():
    """The kernels' row generator (central branch for all, tail branch for the listed few)
    gives exactly the deviates of the one-at-a-time inversion, tails of both signs included."""
    for count in (1, 7, 1024, 100_003):
        z = _kernels.normals(99, 3, count, 2).astype(np.float32)
        fast = _kernels.normals_fast(99, 3, count, 2).astype(np.float32)
        assert np.array_equal(z.view(np.uint32), fast.view(np.uint32))
    assert np.sum(z < -1.97) > 1000 and np.sum(z > 1.97) > 1000  # both tails (p < 0.02425) were exercised


def test_invalid_photocurrent_is_counted_once_per_value():
    flat = np.ones((3, 2500), np.float32)
    flat[0, 0], flat[1, 1], flat[2, 2], flat[2, 2400], flat[1, 3] = np.nan, -np.inf, np.inf, -1e-30, -0.0
    assert count_invalid(flat, nonnegative=True) == 4  # -0.0 is >= 0
    assert count_invalid(flat.astype(np.float64), nonnegative=True) == 4
    assert count_invalid(flat) == 3  # only NaN and the infinities
    big = np.zeros((7, 100, 1000))  # several parallel blocks, a ragged last one
    big[6, 99, 999] = big[0, 0, 0] = np.nan
    assert count_invalid(big) == 2


@pytest.mark.parametrize(
    "current, times, match",
    [
        (np.full((2, 4, 5), -1e-12), [1e-5, 2e-5], "finite and >= 0"),
        (np.full((2, 4, 5), np.nan), [1e-5, 2e-5], "finite and >= 0"),
        (np.full((2, 4, 5), 1e-12), [2e-5, 1e-5], "increase strictly"),
        (np.full((2, 4, 5), 1e-12), [0.0, 1e-5], "increase strictly"),
        (np.full((2, 5, 4), 1e-12), [1e-5, 2e-5], r"shape \(T, 4, 5\)"),
        (np.full((3, 4, 5), 1e-12), [1e-5, 2e-5], "2 times but photocurrent has 3"),
    ],
)
def test_bad_input_is_a_clear_error_and_leaves_state_untouched(current, times, match):
    pr = Photoreceptor(SHAPE, params=REC, noise=FULL, rng=np.random.default_rng(0))
    before = pr.process(np.full((1,) + SHAPE, 1e-12), [1e-6])
    state = (pr.v1.copy(), pr.t_s, pr.step)
    with pytest.raises(ValueError, match=match):
        pr.process(current, times)
    assert np.array_equal(pr.v1, state[0]) and (pr.t_s, pr.step) == state[1:]
    assert before.shape == (1,) + SHAPE


def test_zero_light_with_zero_dark_current_is_an_error():
    pr = Photoreceptor(SHAPE, params=REC, noise=NoiseParams(shot_noise=False, dark_current_a=0.0),
                       rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="> 0 where the dark current is 0"):
        pr.process(np.zeros((1,) + SHAPE), [1e-5])


def test_infinite_bandwidth_follows_the_log_instantly():
    ideal = PhotoreceptorParams(cutoff_hz=math.inf, max_cutoff_hz=math.inf)
    steps = np.array([1e-12, 1e-10, 1e-14])
    _, out = run(ideal, QUIET, steps, 1e-6)
    np.testing.assert_allclose(out[:, 0, 0], np.log(steps + 1e-18), rtol=1e-6)
    with pytest.raises(ValueError, match="finite photoreceptor bandwidth"):
        Photoreceptor(SHAPE, params=ideal, noise=NoiseParams(), rng=np.random.default_rng(0))


@njit
def _lowbias32(x):
    x = np.uint32(x)
    x ^= x >> np.uint32(16)
    x = np.uint32(x * np.uint32(0x7FEB352D))
    x ^= x >> np.uint32(15)
    x = np.uint32(x * np.uint32(0x846CA68B))
    x ^= x >> np.uint32(16)
    return x


@njit
def _field_fingerprints(key, n_steps, n_pixels, former):
    """Per step, a fingerprint of the multiset of the 32-bit values behind one stream's deviates of
    pixels 0 .. n_pixels - 1: the sum of their 64-bit hashes, the same for a field and any shuffle
    of it. ``former``: the 32-bit generator used before (issue 12), else the current one."""
    out = np.empty(n_steps, np.uint64)
    for step in range(n_steps):
        if former:  # mix32(mix32(key ^ mix32(step_lo ^ mix32(step_hi ^ 0x5BD1E995))) ^ mix32(stream * 0x9E3779B9))
            sk = _lowbias32(np.uint32(key) ^ _lowbias32(np.uint32(step) ^ _lowbias32(np.uint32(0x5BD1E995))))
            sk = _lowbias32(sk ^ _lowbias32(np.uint32(1) * np.uint32(0x9E3779B9)))
            block_key = _lowbias32(sk ^ np.uint32(0))  # block starting at pixel 0
        else:
            sk = _kernels.stream_key(key, step, 1)
        acc = np.uint64(0)
        for p in range(n_pixels):
            bits = _lowbias32(block_key ^ np.uint32(p)) if former else _kernels.pixel_bits(sk, p)
            acc += _kernels.mix64(np.uint64(bits))
        out[step] = acc
    return out


def _repeated_pairs(fingerprints):
    _, counts = np.unique(fingerprints, return_counts=True)
    return int(np.sum(counts * (counts - 1) // 2))


def test_no_noise_field_repeats_shuffled_over_many_steps():
    """2^17 steps (1.3 s of 10 us steps) of a 1024-pixel block. The former 32-bit generator hashed
    key ^ pixel with a 32-bit key per step, so steps whose keys agree but in the low 10 bits drew
    the same field, shuffled: ~2^34 / 2^22 = 2048 such pairs expected. The 64-bit generator: none."""
    n_steps, n_pixels = 2**17, 1024
    former = _repeated_pairs(_field_fingerprints(1234, n_steps, n_pixels, True))
    assert 1700 < former < 2400
    assert _repeated_pairs(_field_fingerprints(1234, n_steps, n_pixels, False)) == 0


def test_noise_is_the_same_for_any_threads_and_chunking_across_blocks():
    """2400 pixels: three parallel blocks (the last partial), every noise source on."""
    noise = NoiseParams(shot_noise=True, read_noise_v=1e-3, dark_current_a=3e-15, dark_current_spread=0.3,
                        prnu=0.01, flicker_noise_v=1e-3, flicker_noise_low_hz=1.0, flicker_noise_high_hz=1e3)
    cur = _scene(np.random.default_rng(4), t_steps=30, shape=(40, 60))
    t = 1e-5 * np.arange(1, 31)
    runs = []
    threads = numba.get_num_threads()
    try:
        for n in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(n)
            for cuts in ([0, 30], [0, 1, 13, 30]):
                pr = Photoreceptor(cur.shape[1:], params=REC, noise=noise, rng=np.random.default_rng(3))
                runs.append(np.concatenate([pr.process(cur[a:b], t[a:b]) for a, b in zip(cuts, cuts[1:])]))
    finally:
        numba.set_num_threads(threads)
    assert all(np.array_equal(runs[0], r) for r in runs[1:])
    assert np.std(runs[0][-1] - np.log(cur[-1])) > 0  # noise is on
