"""Cost per simulated second of the long-step DVS prototype against today's short steps (issue 37, item 1).

davis346 on a static textured scene (log-normal texture, sigma 0.5 ln, around a mean chip illuminance), 2 kHz
frames split into the driver's sub-steps (``gevsim.emulation.driver.substeps``' rule) for the short path; the
long path (:class:`gevsim.events.longstep.LongStepBrightness`) gets the frames. Both start from the same
started sensor; photoreceptor, noise and DVS are timed, the photocurrent is given. The two paths alternate
(ABAB) in one process on the same threads; the ratio of their times is the figure (the VM is shared).

    .venv/bin/python benchmarks/long_steps.py [--sizes 96x72 346x260] [--lux 0.1 10 1000] [--span 0.128] [--no-leak]
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import math
import time

import numpy as np

from gevsim import _portable as pm
from gevsim.events import _longstep
from gevsim.events.longstep import LongStepBrightness
from gevsim.pixel import load_preset
from gevsim.pixel.noise import coarsest_step_s
from gevsim.validation.measure import photocurrent_a, running_sensor, start_running

FRAME_S = 5e-4


def scene(shape: tuple[int, int], preset, chip_lux: float) -> np.ndarray:
    """Photocurrent (A) of a static log-normal texture (sigma 0.5 ln) around ``chip_lux``."""
    z = np.random.default_rng(7).standard_normal(shape)
    return photocurrent_a(preset, chip_lux) * pm.exp(0.5 * z - 0.125)


def short_path(pr, dvs, level: np.ndarray, t: np.ndarray, t0: float, n_sub: int) -> int:
    """Today's path over the frames ``t``: each split into n_sub sub-steps, light held. Returns events."""
    starts = np.r_[t0, t[:-1]]
    fine = (starts[:, None] + (t - starts)[:, None] * (np.arange(1, n_sub + 1) / n_sub)[None, :])
    fine[:, -1] = t
    fine = fine.ravel()
    n = 0
    step = max(1, 2_000_000 // level.size)
    for a in range(0, len(fine), step):
        tt = fine[a:a + step]
        n += len(dvs.process(pr.process(np.broadcast_to(level, (len(tt),) + level.shape), tt), tt))
    return n


def run(shape: tuple[int, int], chip_lux: float, span_s: float, reps: int, leak: bool = True) -> dict:
    preset = load_preset("davis346")
    if not leak:  # what the leak costs: without it no level drifts toward its threshold
        preset = dataclasses.replace(preset, events=dataclasses.replace(preset.events, leak_rate_hz=0.0,
                                                                          leak_light_hz_per_a=0.0))
    level = scene(shape, preset, chip_lux)
    limit = coarsest_step_s(preset.photoreceptor, preset.noise, float(level.max()))
    n_sub = max(1, math.ceil(FRAME_S / limit - 1e-9)) if limit is not None else 1
    pr, dvs = running_sensor(preset, shape, 1)
    t0 = start_running(pr, dvs, level[None], FRAME_S / n_sub, burn_in_s=FRAME_S)
    frames = int(round(span_s / FRAME_S))
    t = t0 + FRAME_S * np.arange(1, frames + 1)
    light = np.broadcast_to(level, (frames,) + shape)
    # warm the compiled code on a copy (not timed)
    LongStepBrightness(copy.deepcopy(pr), copy.deepcopy(dvs), frame_s=FRAME_S, n_sub=n_sub).process(light[:2], t[:2])
    short_s, long_s, n_short, n_long, advances = [], [], 0, 0, 0
    for _ in range(reps):  # ABAB
        p2, d2 = copy.deepcopy(pr), copy.deepcopy(dvs)
        a = time.perf_counter()
        n_short += short_path(p2, d2, level, t, t0, n_sub)
        short_s.append(time.perf_counter() - a)
        long = LongStepBrightness(copy.deepcopy(pr), copy.deepcopy(dvs), frame_s=FRAME_S, n_sub=n_sub)
        a = time.perf_counter()
        for c in range(0, frames, 256):  # chunks of 256 frames (the driver's chunk_steps), whole groups of 2^K
            n_long += len(long.process(light[c:c + 256], t[c:c + 256]))
        long_s.append(time.perf_counter() - a)
        advances += int(long.stats[:, _longstep.ADVANCES].sum())
    px_s = shape[0] * shape[1] * span_s * reps
    return {"n_sub": n_sub, "short_s_per_s": min(short_s) / span_s, "long_s_per_s": min(long_s) / span_s,
            "ratio": min(short_s) / min(long_s), "short_ev": n_short / px_s, "long_ev": n_long / px_s,
            "advances": advances / px_s, "base": n_sub / FRAME_S}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["96x72", "346x260"])
    ap.add_argument("--lux", nargs="+", type=float, default=[0.1, 10.0, 1000.0])
    ap.add_argument("--span", type=float, default=0.128, help="simulated seconds per run (default 0.128)")
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--no-leak", action="store_true", help="the preset with its DVS leak off")
    args = ap.parse_args()
    print("| size | chip lux | sub-steps | short s/sim-s | long s/sim-s | short / long | ev/px/s short, long |"
          " advances/px/s (base steps/s) |")
    print("|---|---|---|---|---|---|---|---|")
    for size in args.sizes:
        w, h = (int(v) for v in size.split("x"))
        for lux in args.lux:
            r = run((h, w), lux, args.span, args.reps, leak=not args.no_leak)
            print(f"| {size} | {lux:g} | {r['n_sub']} | {r['short_s_per_s']:.2f} | {r['long_s_per_s']:.3f} | "
                  f"{r['ratio']:.1f}x | {r['short_ev']:.2f}, {r['long_ev']:.2f} | "
                  f"{r['advances']:.0f} ({r['base']:.0f}) |", flush=True)


if __name__ == "__main__":
    main()
