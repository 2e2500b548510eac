"""CSDVS: the diffuser preserves constants and decays at the resistive-line rate; a
uniform flicker cancels with an instantaneous surround; chunking invariance; the same events
as the former per-step kernel, with the parallel loops opened once per chunk."""

import hashlib
import math

import numpy as np
import pytest
from numba import njit

from gevsim import _portable as pm
from gevsim.events.center_surround import CenterSurroundEmulator, centre_minus_surround
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


def test_events_are_bit_identical_to_the_per_step_kernel():
    """SHA-256 of the events and final surround of a three-chunk run, computed with the former
    kernel (three parallel loops per step, commit fbb08e6) before the kernel was restructured.
    Recomputed for issue 21: the surround's decay is gevsim._portable.exp (numpy's exp differs in
    the last bit between AVX-512 and AVX2 CPUs); the 634 events are the same, the surround's last
    bits moved. Recomputed again for issue 22: changes during the refractory period are forgotten
    (the change amplifier is held in reset), 631 events."""
    rng = np.random.default_rng(7)
    h, w, n = 23, 31, 120
    base = pm.log(0.05 + rng.random((h, w)))
    t = np.cumsum(rng.uniform(5e-6, 15e-6, n))
    v = (base[None] + 0.3 * pm.sin(2 * np.pi * 300 * t)[:, None, None] * rng.random((h, w))[None]
         + np.cumsum(rng.normal(0, 0.02, (n, h, w)), axis=0)).astype(np.float32)
    p = EventParams(threshold_mismatch_ln=0.02, refractory_s=1e-5)
    em = CenterSurroundEmulator((h, w), p, surround_length_px=1.7, surround_tau_s=2e-4, rng=np.random.default_rng(3))
    ev = np.concatenate([em.process(v[a:b], t[a:b]) for a, b in ((0, 1), (1, 40), (40, 120))])
    digest = hashlib.sha256(ev.tobytes())
    digest.update(em.surround.tobytes())
    assert len(ev) == 631
    assert digest.hexdigest() == "f6ccee59da6be702edd8c2867812dc93853b33bc3595296f73aba6ff5669f511"


def _parallel_loops_inside_sequential_loops(kernel, *args):
    """(number of top-level parallel loops, how many of them sit inside a sequential loop) of a
    fresh parallel compilation of ``kernel``, from numba's parfor IR: a parallel loop inside a
    loop forks and joins the thread pool on every iteration."""
    from numba.core.analysis import compute_cfg_from_blocks
    from numba.parfors.parfor import Parfor

    compiled = njit(parallel=True)(kernel.py_func)
    compiled(*args)
    ir = compiled.get_metadata(compiled.signatures[0])["parfor_diagnostics"].func_ir
    in_loops = set()
    for loop in compute_cfg_from_blocks(ir.blocks).loops().values():
        in_loops |= set(loop.body)
    labels = [label for label, block in ir.blocks.items() for st in block.body if isinstance(st, Parfor)]
    return len(labels), sum(label in in_loops for label in labels)


def test_csdvs_opens_its_parallel_loops_once_per_chunk_not_per_step():
    h, w, n = 5, 6, 3
    em = CenterSurroundEmulator((h, w), EventParams(), rng=np.random.default_rng(0))
    args = (np.zeros((n, h, w), np.float32), np.zeros(n), np.zeros((h, w)), *em._x, *em._y, em.c,
            np.empty((n, h, w)))
    total, per_step = _parallel_loops_inside_sequential_loops(centre_minus_surround, *args)
    assert (total, per_step) == (2, 0)  # rows, then columns; the former kernel had 3 inside its loop over steps
