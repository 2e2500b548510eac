"""The full davis346 pixel path (photoreceptor with noise, DVS, gradient) on a static scene: the driver's short
steps against long steps with the crossing rule on both emulators (issue 37, item 1, done-when 2).

A davis346 array on a static log-normal texture (``bridge_crossings.scene``) is settled, its noise-free twin taken, its
DVS levels drawn and burnt in; then from copies of that start, for ``--span`` seconds:
- ``reference``: photoreceptor, DVS and gradient comparators at the driver's step (20 us);
- ``bridged``: photoreceptor, its noise-free twin, DVS and gradient with the crossing rule at steps of h.
Rates: DVS events per pixel and gradient events per comparator per second, each path's seconds per simulated
second, and their ratio (side by side in one process). The gradient's reference undercounts by 4-7 % at 20 us
(docs/bridge.md): its ratio is expected at 1.04-1.08.

    PYTHONPATH=benchmarks .venv/bin/python benchmarks/bridged_path.py [--lux 0.1 10 1000] [--steps-us 2000]
"""

from __future__ import annotations

import argparse
import copy
import time

import numpy as np
from bridge_crossings import lighting, scene
from bridged_dvs import started

from gevsim.emulation.emulators import GradientConfig
from gevsim.events import GradientEmulator
from gevsim.pixel import load_preset

REF_STEP_S = 2e-5


def run_path(pr, bridging, dvs, grad, light, t0: float, span_s: float, h: float, bridged: bool):
    """(DVS events, gradient events, seconds) over (t0, t0 + span_s] at steps of h."""
    t = t0 + h * np.arange(1, int(round(span_s / h)) + 1)
    chunk = max(1, 1_000_000 // dvs.threshold_on_ln.size)
    n_dvs = n_grad = 0
    tick = time.perf_counter()
    for a in range(0, len(t), chunk):
        tt = t[a:a + chunk]
        cur = np.ascontiguousarray(light(tt, h), dtype=np.float32)
        v = pr.process(cur, tt)
        bridge = bridging.bridge(cur, tt) if bridged else None
        n_dvs += len(dvs.process(v, tt, bridge=bridge))
        n_grad += len(grad.process(v, tt, bridge=bridge))
    return n_dvs, n_grad, time.perf_counter() - tick


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lux", type=float, nargs="*", default=[0.1, 10.0, 1000.0])
    ap.add_argument("--steps-us", type=float, nargs="*", default=[2000.0])
    ap.add_argument("--span", type=float, default=0.5)
    ap.add_argument("--size", type=int, default=64)
    args = ap.parse_args()
    preset = load_preset("davis346")
    shape = (args.size, args.size)
    px, comparators = shape[0] * shape[1], 2 * shape[0] * (shape[1] - 1)
    print(f"davis346 {args.size}x{args.size}, static, {args.span:g} s; DVS ev/px/s, gradient ev/comparator/s, "
          "seconds per simulated second")
    print("| chip lux | h | DVS: 20 us / bridged | gradient: 20 us / bridged | s/s: 20 us / bridged | cheaper |")
    print("| --- | --- | --- | --- | --- | --- |")
    for lux in args.lux:
        level = scene(shape, preset, lux)
        light = lighting(level, 0.0, 0.0, 5.0)
        pr, bridging, dvs, t0 = started(preset, level, REF_STEP_S, light)
        grad = GradientEmulator(shape, thresholds_ln=GradientConfig.thresholds_ln, rng=np.random.default_rng(3),
                                offset_sigma_ln=preset.events.comparator_offset_v / preset.photoreceptor.volts_per_ln)
        tt = np.array([t0 + 1e-6])
        grad.process(pr.process(light(tt, 1e-6), tt), tt)
        bridging.twin.process(light(tt, 1e-6), tt)
        t0 = float(tt[0])
        state = (pr, bridging, dvs, grad)
        ref = run_path(*copy.deepcopy(state), light, t0, args.span, REF_STEP_S, False)
        for h_us in args.steps_us:
            br = run_path(*copy.deepcopy(state), light, t0, args.span, h_us * 1e-6, True)
            ref_s, br_s = ref[2] / args.span, br[2] / args.span
            print(f"| {lux:g} | {h_us:g} us | {ref[0] / px / args.span:.2f} / {br[0] / px / args.span:.2f} | "
                  f"{ref[1] / comparators / args.span:.0f} / {br[1] / comparators / args.span:.0f} | "
                  f"{ref_s:.2f} / {br_s:.2f} | {ref_s / br_s:.1f}x |", flush=True)


if __name__ == "__main__":
    main()
