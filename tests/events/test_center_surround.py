"""CSDVS: the diffuser preserves constants and decays at the resistive-line rate; a
uniform flicker cancels with an instantaneous surround; chunking invariance."""

import math

import numpy as np
import pytest

from gevsim.events.center_surround import CenterSurroundEmulator
from gevsim.pixel import EventParams


def test_diffuser_preserves_constants_and_decays_like_a_resistive_line():
    em = CenterSurroundEmulator((1, 201), EventParams(), surround_length_px=3.0, rng=np.random.default_rng(0))
    assert np.allclose(em.spatial_surround(np.full((1, 201), 2.5)), 2.5)
    impulse = np.zeros((1, 201))
    impulse[0, 100] = 1.0
    s = em.spatial_surround(impulse)[0]
    c = 9.0
    r = 1 + 1 / (2 * c) - math.sqrt((1 + 1 / (2 * c)) ** 2 - 1)  # root of c r^2 - (1 + 2c) r + c = 0
    np.testing.assert_allclose(s[101:110] / s[100:109], r, rtol=1e-9)
    assert s.sum() == pytest.approx(1.0)  # reflecting borders conserve charge


def test_uniform_flicker_cancels_with_an_instant_surround():
    rng = np.random.default_rng(1)
    scene = np.log(0.05 + rng.random((16, 20)))
    t = np.arange(300) * 50e-6
    v = scene[None] + np.log(1 + 0.9 * np.sin(2 * np.pi * 100 * t))[:, None, None]
    instant = CenterSurroundEmulator((16, 20), EventParams(), surround_tau_s=0.0, rng=rng).process(v, t)
    slow = CenterSurroundEmulator((16, 20), EventParams(), surround_tau_s=5e-3, rng=rng).process(v, t)
    assert len(instant) == 0 and len(slow) > 100


def test_moving_edge_gives_events():
    x = np.arange(24)
    t = np.arange(60) * 1e-4
    v = np.stack([np.broadcast_to(np.where(x < 4 + k // 4, 0.0, 1.0), (10, 24)) for k in range(60)])
    ev = CenterSurroundEmulator((10, 24), EventParams(), surround_tau_s=0.0, rng=np.random.default_rng(0)).process(v, t)
    assert len(ev) > 0 and set(np.unique(ev["p"])) == {True, False}


def test_chunked_equals_one_shot():
    rng = np.random.default_rng(2)
    v = np.cumsum(rng.normal(0, 0.05, (50, 12, 14)), axis=0)
    t = np.cumsum(rng.uniform(1e-5, 2e-5, 50))
    p = EventParams(threshold_mismatch_ln=0.02)
    one = CenterSurroundEmulator((12, 14), p, rng=np.random.default_rng(3)).process(v, t)
    em = CenterSurroundEmulator((12, 14), p, rng=np.random.default_rng(3))
    parts = np.concatenate([em.process(v[a:b], t[a:b]) for a, b in ((0, 1), (1, 20), (20, 50))])
    assert len(one) > 50
    np.testing.assert_array_equal(one, parts)


@pytest.mark.parametrize("kw, match", [(dict(surround_length_px=0.0), "surround_length_px"),
                                       (dict(surround_tau_s=-1.0), "surround_tau_s")])
def test_bad_parameters(kw, match):
    with pytest.raises(ValueError, match=match):
        CenterSurroundEmulator((4, 4), EventParams(), rng=np.random.default_rng(0), **kw)
