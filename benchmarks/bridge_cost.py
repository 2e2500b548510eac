"""What the Rice crossing rule (:mod:`gevsim.events.bridge`) would cost on the davis346 path at the frame step,
against the physics-valid sub-steps and v2e (issue 37, item 1: is the rule cheap enough to pay?).

On flicker_pan (2 kHz frames, 346x260) the script times, chunk by chunk and alternately in one process:

- ``sub-steps``: today's physics-valid path (photoreceptor with every noise, DVS, gradient at 22 sub-steps per
  frame: ``physics_valid_path.sub_stepped``);
- ``frame step + rule``: the same chain at the frame step, a noise-free twin of the photoreceptor (the rule needs
  each pixel's noise, the output minus its noise-free value), each frame's noise law
  (``Photoreceptor.noise_components`` at its photocurrent) and the rule on every DVS comparator (ON and OFF
  levels from its level, the leak included) and every gradient comparator (the difference of two neighbours'
  noise, three components; its levels from its ternary state). The rule's probabilities are computed, not
  acted on: this times what wiring it in would add, not its events;
- ``v2e noisy DVS`` (when v2e is importable, as in ``physics_valid_path.py``).

    PYTHONPATH=.:/tmp/v2e_src:/tmp/v2edeps .venv/bin/python benchmarks/bridge_cost.py [--threads 2] [--repeat 3]

Also printed: the share of comparator-frames the rule integrates (a level within reach of the noise).
"""

from __future__ import annotations

import argparse
import copy
import math
import statistics
import time

import numba
import numpy as np
from event_throughput import DN_FLOOR, Chunk, GevsimStages, inputs
from physics_valid_path import sub_stepped

from gevsim.events.bridge import crossings
from gevsim.pixel import load_preset
from gevsim.pixel.noise import coarsest_step_s


def noise_free_twin(pr):
    """A copy of ``pr`` (the same fixed patterns, not yet started) with every temporal noise off."""
    twin = copy.deepcopy(pr)
    twin.shot_q = twin.amp_ln2_hz = 0.0
    twin.fn_var = np.zeros_like(twin.fn_var)
    twin.fn = np.zeros_like(twin.fn)
    return twin


def gradient_gaps(g0, g1, state, theta):
    """The gaps to the levels each gradient comparator can cross from its state (hysteresis 0): from 0 the
    levels +-theta; from +1 (-1) the return to 0 at theta (-theta). Far gaps (1e3) for the levels it cannot."""
    big = 1e3
    up0 = np.where(state == 0, theta - g0, np.where(state < 0, -theta - g0, big))
    up1 = np.where(state == 0, theta - g1, np.where(state < 0, -theta - g1, big))
    dn0 = np.where(state == 0, g0 + theta, np.where(state > 0, g0 - theta, big))
    dn1 = np.where(state == 0, g1 + theta, np.where(state > 0, g1 - theta, big))
    return (up0, up1), (dn0, dn1)


class RulePath:
    """The frame-step chain plus the rule on every comparator (see the module docstring)."""

    def __init__(self, shape, preset):
        self.st = GevsimStages(shape, preset, seed=0, csdvs=False)
        self.twin = noise_free_twin(self.st.pr)
        self.beta = 2.0 * math.pi * preset.photoreceptor.second_pole_hz
        self.shape = shape
        self.seconds = {"chain": 0.0, "twin": 0.0, "law": 0.0, "DVS rule": 0.0, "gradient rule": 0.0}
        self.open = [0, 0, 0, 0]  # DVS sides open, DVS sides, gradient sides open, gradient sides

    def frame(self, current, t_prev, t_end) -> None:
        st, s = self.st, self.seconds
        h = t_end - t_prev
        y_prev = None if st.pr.t_s == 0.0 else self.y_prev
        ref, v_prev = st.dvs.ref.copy(), st.dvs.v_prev.copy()
        g_state, g_prev = st.grad.state.copy(), st.grad.g_prev.copy()
        tick = time.perf_counter()
        y = st.pr.process(current[None], [t_end])[0]
        st.dvs.process(y[None], [t_end])
        st.grad.process(y[None], [t_end])
        tock = time.perf_counter()
        s["chain"] += tock - tick
        mu = self.twin.process(current[None], [t_end])[0]
        tick = time.perf_counter()
        s["twin"] += tick - tock
        var, rate = st.pr.noise_components(current.reshape(-1) * st.pr.gain + st.pr.dark_a)
        tock = time.perf_counter()
        s["law"] += tock - tick
        x1 = (y - mu).reshape(-1).astype(np.float64)
        if y_prev is not None:
            x0 = self.x_prev
            dvs = st.dvs
            leak = dvs.leak_ln_per_s + (dvs.leak_light * np.exp(v_prev) if dvs.leak_light.size else 0.0)
            d0 = v_prev - ref
            d1 = y.reshape(-1) - ref + leak * h
            on, off = dvs.threshold_on_ln, dvs.threshold_off_ln
            p_on, p_off, _, _ = crossings(x0, x1, (on - d0, on - d1), (off + d0, off + d1), h, var, rate,
                                          self.beta)
            tick = time.perf_counter()
            s["DVS rule"] += tick - tock
            self.open[0] += int(np.count_nonzero(p_on > 1e-12) + np.count_nonzero(p_off > 1e-12))
            self.open[1] += 2 * x1.size
            hh, ww = self.shape
            g1 = np.stack([np.zeros(self.shape), np.zeros(self.shape)])
            yy = y.astype(np.float64)
            g1[0, :, :-1] = yy[:, 1:] - yy[:, :-1]
            g1[1, :-1, :] = yy[1:, :] - yy[:-1, :]
            g1 -= st.grad.offset
            xx0, xx1 = x0.reshape(self.shape), x1.reshape(self.shape)
            vr, rr = var.reshape(-1, hh, ww), rate.reshape(-1, hh, ww)
            for axis, (a, b) in enumerate([(np.s_[:, 1:], np.s_[:, :-1]), (np.s_[1:, :], np.s_[:-1, :])]):
                n0, n1 = xx0[a] - xx0[b], xx1[a] - xx1[b]
                gv = np.stack([vr[0][a], vr[0][b], vr[1][a] + vr[1][b]]).reshape(3, -1)
                gr = np.stack([rr[0][a], rr[0][b], rr[1][a]]).reshape(3, -1)
                up, dn = gradient_gaps(g_prev[axis][b], g1[axis][b], g_state[axis][b], st.grad.theta[axis][b])
                q_up, q_dn, _, _ = crossings(n0, n1, up, dn, h, gv, gr, self.beta)
                self.open[2] += int(np.count_nonzero(q_up > 1e-12) + np.count_nonzero(q_dn > 1e-12))
                self.open[3] += 2 * n0.size
            s["gradient rule"] += time.perf_counter() - tick
        self.y_prev, self.x_prev = y, x1

    def chunk(self, c: Chunk) -> float:
        before = sum(self.seconds.values())
        t_prev = float(c.t[0]) - float(c.t[1] - c.t[0])
        for current, t_end in zip(c.current, c.t):
            self.frame(current, t_prev, float(t_end))
            t_prev = float(t_end)
        return sum(self.seconds.values()) - before


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="346x260")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--steps", type=int, default=20, help="frames per chunk")
    ap.add_argument("--repeat", type=int, default=3, help="timed chunks (after one warm-up chunk)")
    args = ap.parse_args()
    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    try:
        import torch
        from event_throughput import V2e
        torch.set_num_threads(1)  # v2e's faster count on this VM (benchmarks/README.md)
        v2e = V2e(noisy=True, seed=0)
    except Exception as exc:  # v2e is optional here
        print(f"v2e not run: {exc}")
        v2e = None
    preset = load_preset("davis346")
    w, h = (int(x) for x in args.size.split("x"))
    inp = next(iter(inputs(["flicker_pan"], h, w, args.steps, preset, preset, chunks=args.repeat + 1,
                           cache="/tmp/gevsim-bench-cache", office_spp=2)))
    rule, sub = RulePath((h, w), preset), GevsimStages((h, w), preset, seed=0, csdvs=False)
    rows: dict[str, list[float]] = {"sub-steps": [], "frame step + rule": [], "v2e noisy DVS (1 thread)": []}
    for j in range(args.repeat + 1):
        current, t = inp.chunk(j)
        limit = coarsest_step_s(preset.photoreceptor, preset.noise, float(current.max()))
        k = math.ceil(float(t[1] - t[0]) / limit - 1e-9)
        dn = current * np.float32(255.0 / float(current.max()))
        c = Chunk(current, t, dn, np.log(np.maximum(dn, np.float32(DN_FLOOR))))
        parts_before = dict(rule.seconds)
        s_rule = rule.chunk(c)
        s_sub = sub_stepped(sub, c, k)
        s_v2e = v2e.run(c)["v2e noisy"][0] if v2e is not None else math.nan
        if j:
            rows["sub-steps"].append(s_sub)
            rows["frame step + rule"].append(s_rule)
            rows["v2e noisy DVS (1 thread)"].append(s_v2e)
            parts = {key: rule.seconds[key] - parts_before[key] for key in rule.seconds}
            print(f"chunk {j}: " + ", ".join(f"{key} {v:.3f} s" for key, v in parts.items()), flush=True)
    print(f"flicker_pan {w}x{h}, {args.threads} gevsim thread(s), {args.steps} frames of 500 us per chunk, "
          f"{k} sub-steps per frame; median s per chunk:")
    for label, secs in rows.items():
        print(f"  {label:28s} {statistics.median(secs):.4f}")
    med = {key: statistics.median(v) for key, v in rows.items()}
    print(f"  sub-steps / (frame step + rule) = {med['sub-steps'] / med['frame step + rule']:.2f}x; "
          f"v2e / (frame step + rule) = {med['v2e noisy DVS (1 thread)'] / med['frame step + rule']:.2f}x; "
          f"v2e / sub-steps = {med['v2e noisy DVS (1 thread)'] / med['sub-steps']:.2f}x")
    print(f"  sides the rule integrated: DVS {rule.open[0] / max(rule.open[1], 1):.1%}, "
          f"gradient {rule.open[2] / max(rule.open[3], 1):.1%} (all chunks)")


if __name__ == "__main__":
    main()
