"""The DVS with crossings between long samples (``BrightnessEmulator.process(..., bridge=...)``) against the
driver's physics-valid short steps: noise-event rates and cost per simulated second (issue 37, item 1).

A davis346 array on a static log-normal texture (``bridge_crossings.scene``), optionally times exp(A sin(2 pi f t)),
is settled, its noise-free twin taken (``Photoreceptor.noise_free_twin``), its levels drawn and burnt in; then
from copies of that start:
- ``reference``: photoreceptor and DVS at the driver's step (``coarsest_step_s``, at most 20 us);
- ``bridged``: photoreceptor, its noise-free twin and the DVS with the crossing rule at steps of h.
Rates are events per pixel per second with 95 % intervals over pixels; ON share; seconds for each path.

    PYTHONPATH=benchmarks .venv/bin/python benchmarks/bridged_dvs.py [--lux 0.1 10 1000] [--steps-us 500 2000]
"""

from __future__ import annotations

import argparse
import copy
import math
import time

import numpy as np
from bridge_crossings import lighting, rate, scene

from gevsim.emulation.bridging import Bridging
from gevsim.emulation.config import BURN_IN_S
from gevsim.emulation.start import start_levels
from gevsim.pixel import load_preset
from gevsim.pixel.noise import coarsest_step_s
from gevsim.validation.measure import pixel_counts, running_sensor


def started(preset, level: np.ndarray, step: float, light):
    """Photoreceptor, its :class:`~gevsim.emulation.bridging.Bridging` (noise-free twin and law) and DVS, settled on
    ``level``, levels drawn, burnt in over BURN_IN_S at ``step`` (light(t, dt) from t = 0). Returns them and the
    time the burn-in ended."""
    pr, dvs = running_sensor(preset, level.shape, 1)
    pr.settle(level[None], np.full(1, step))
    bridging = Bridging(pr)
    start_levels(pr, [dvs])
    n = int(math.ceil(BURN_IN_S / step - 1e-9))
    t = step * np.arange(1, n + 1)
    for a in range(0, n, 256):
        tt = t[a:a + 256]
        cur = light(tt, step)
        dvs.process(pr.process(cur, tt), tt)
        bridging.twin.process(cur, tt)
    return pr, bridging, dvs, n * step


def run_path(pr, bridging, dvs, light, t0: float, span_s: float, h: float, bridged: bool):
    """Events of the chain over (t0, t0 + span_s] at steps of h, with or without the crossing rule."""
    t = t0 + h * np.arange(1, int(round(span_s / h)) + 1)
    chunk = max(1, 2_000_000 // dvs.threshold_on_ln.size)
    out = []
    for a in range(0, len(t), chunk):
        tt = t[a:a + chunk]
        cur = np.ascontiguousarray(light(tt, h), dtype=np.float32)
        v = pr.process(cur, tt)
        out.append(dvs.process(v, tt, bridge=bridging.bridge(cur, tt) if bridged else None))
    return np.concatenate(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lux", type=float, nargs="*", default=[0.1, 10.0, 1000.0])
    ap.add_argument("--steps-us", type=float, nargs="*", default=[500.0, 2000.0])
    ap.add_argument("--span", type=float, default=1.0)
    ap.add_argument("--size", default="64x64")
    ap.add_argument("--sine-ln", type=float, default=0.0)
    ap.add_argument("--sine-hz", type=float, default=5.0)
    args = ap.parse_args()
    w, hgt = (int(x) for x in args.size.split("x"))
    preset = load_preset("davis346")
    print(f"davis346 {w}x{hgt}, {'static' if not args.sine_ln else f'x exp({args.sine_ln} sin 2 pi {args.sine_hz} Hz t)'}"
          f", {args.span:g} s; ev/px/s (95 %), ON share, seconds")
    print("| chip lux | reference | h | sampled only | bridged | bridged / reference | cost ratio |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for lux in args.lux:
        level = scene((hgt, w), preset, lux)
        step = min(2e-5, coarsest_step_s(preset.photoreceptor, preset.noise, float(level.max())) or 2e-5)
        light = lighting(level, 0.0, args.sine_ln, args.sine_hz)
        pr, bridging, dvs, t0 = started(preset, level, step, light)
        tick = time.perf_counter()
        ev = run_path(copy.deepcopy(pr), copy.deepcopy(bridging), copy.deepcopy(dvs), light, t0, args.span, step, False)
        s_ref = time.perf_counter() - tick
        r_ref = rate(pixel_counts(ev, (hgt, w)), args.span)
        on_ref = float(np.mean(ev["p"])) if len(ev) else math.nan
        for h_us in args.steps_us:
            h = h_us * 1e-6
            ev_s = run_path(copy.deepcopy(pr), copy.deepcopy(bridging), copy.deepcopy(dvs), light, t0, args.span, h,
                            False)
            tick = time.perf_counter()
            ev_b = run_path(copy.deepcopy(pr), copy.deepcopy(bridging), copy.deepcopy(dvs), light, t0, args.span, h,
                            True)
            s_b = time.perf_counter() - tick
            r_s = rate(pixel_counts(ev_s, (hgt, w)), args.span)
            r_b = rate(pixel_counts(ev_b, (hgt, w)), args.span)
            print(f"| {lux:g} | {r_ref[0]:.3f} ± {r_ref[1]:.3f} (ON {on_ref:.2f}), {s_ref:.2f} s | {h_us:g} us | "
                  f"{r_s[0]:.3f} ± {r_s[1]:.3f} | {r_b[0]:.3f} ± {r_b[1]:.3f} (ON {float(np.mean(ev_b['p'])):.2f}), "
                  f"{s_b:.2f} s | {r_b[0] / r_ref[0]:.3f} | {s_ref / s_b:.1f}x |", flush=True)


if __name__ == "__main__":
    main()
