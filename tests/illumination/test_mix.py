"""Mixing basis images with waveform weights."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim.illumination import DC, PWM, Fluorescent, Sinusoid, mix, weights_at


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.mark.parametrize("shape", [(3, 4, 5), (2, 4, 5, 3)])
def test_mix_equals_manual_sum(rng, shape):
    basis = rng.random(shape)
    w = rng.random(shape[0])
    manual = sum(w[k] * basis[k] for k in range(shape[0]))
    np.testing.assert_allclose(mix(basis, w), manual, rtol=1e-13)
    wt = rng.random((6, shape[0]))
    out = mix(basis, wt)
    assert out.shape == (6, *shape[1:]) and out.dtype == np.float64
    for i in range(6):
        np.testing.assert_allclose(out[i], sum(wt[i, k] * basis[k] for k in range(shape[0])), rtol=1e-13)


@settings(max_examples=30, deadline=None)
@given(a=st.floats(-10, 10), b=st.floats(-10, 10), seed=st.integers(0, 2**32 - 1))
def test_mix_is_linear(a, b, seed):
    r = np.random.default_rng(seed)
    basis = r.random((3, 2, 4))
    u, v = r.random(3), r.random(3)
    np.testing.assert_allclose(mix(basis, a * u + b * v), a * mix(basis, u) + b * mix(basis, v),
                               rtol=1e-9, atol=1e-9)


def test_mix_keeps_float32(rng):
    basis = rng.random((2, 3, 3)).astype(np.float32)
    out = mix(basis, [0.5, 2.0])
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, 0.5 * basis[0] + 2.0 * basis[1], rtol=1e-6)
    assert mix(basis.astype(np.float16), [1.0, 1.0]).dtype == np.float64


def test_mix_rejects_bad_shapes(rng):
    with pytest.raises(ValueError, match="3 light groups"):
        mix(rng.random((2, 3, 3)), [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"basis must have shape"):
        mix(rng.random((3, 3)), [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"weights must have shape"):
        mix(rng.random((2, 3, 3)), np.ones((1, 1, 2)))
    with pytest.raises(ValueError, match="finite"):
        mix(rng.random((2, 3, 3)), [1.0, np.nan])


def test_weights_at_values_and_averages():
    wfs = [DC(), Sinusoid(100.0), PWM(100.0, 0.5)]
    t = np.array([0.0, 0.0025, 0.0075])
    w = weights_at(wfs, t)
    assert w.shape == (3, 3)
    np.testing.assert_allclose(w, [[1, 1, 2], [1, 2, 2], [1, 0, 0]], atol=1e-12)
    avg = weights_at(wfs, [0.0, 0.003], average_over_s=0.01)  # one full period: mean 1
    np.testing.assert_allclose(avg, 1.0, atol=1e-12)
    half = weights_at(wfs, [0.0], average_over_s=[0.005])
    np.testing.assert_allclose(half, [[1.0, 1 + 2 / np.pi, 2.0]], atol=1e-12)
    assert weights_at(wfs, 0.001).shape == (1, 3)


def test_weights_at_then_mix_gives_irradiance_sequence(rng):
    basis = rng.random((2, 4, 4))
    wfs = [Fluorescent(), DC()]
    t = np.linspace(0, 0.02, 9)
    e = mix(basis, weights_at(wfs, t))
    np.testing.assert_allclose(e[3], Fluorescent()(t[3]) * basis[0] + basis[1])


def test_weights_at_rejects_bad_input():
    with pytest.raises(TypeError, match=r"waveforms\[1\]"):
        weights_at([DC(), "pwm"], [0.0])
    with pytest.raises(ValueError, match="t_s must be"):
        weights_at([DC()], np.zeros((2, 2)))
    with pytest.raises(ValueError, match="average_over_s"):
        weights_at([DC()], [0.0], average_over_s=0.0)
    with pytest.raises(ValueError, match="average_over_s"):
        weights_at([DC()], [0.0, 1.0], average_over_s=[1.0, 2.0, 3.0])


def test_mix_poses_blends_the_poses_around_each_time():
    from gevsim.illumination import mix_poses

    rng = np.random.default_rng(3)
    basis = rng.random((3, 2, 4, 5))  # poses at 0, 1, 3 s; two light groups
    times = np.array([0.0, 1.0, 3.0])
    t = np.array([-1.0, 0.0, 0.25, 2.0, 3.0, 9.0])
    w = rng.random((len(t), 2))
    got = mix_poses(basis, times, t, w)
    pose = [basis[0], basis[0], 0.75 * basis[0] + 0.25 * basis[1], 0.5 * basis[1] + 0.5 * basis[2], basis[2],
            basis[2]]  # the end poses hold outside
    expect = np.stack([np.tensordot(w[i], pose[i], axes=1) for i in range(len(t))])
    np.testing.assert_allclose(got, expect, rtol=1e-12)
    np.testing.assert_array_equal(mix_poses(basis[:1], times[:1], t, w), mix(basis[0], w))
    assert mix_poses(basis.astype(np.float32), times, t, w).dtype == np.float32
    with pytest.raises(ValueError, match="weights must have shape \\(6, 2\\)"):
        mix_poses(basis, times, t, w[:, :1])
    with pytest.raises(ValueError, match="basis_times_s must have shape \\(3,\\)"):
        mix_poses(basis, times[:2], t, w)
