"""The full davis346 path at the step its physics needs, side by side with v2e (issue 37's headline ratio).

``event_throughput.py`` steps gevsim's davis346 path at the input's own 500 us frames. A physics-valid
``gevsim emulate`` of the same frames splits each into ``k = ceil(500 us / coarsest_step_s)`` equal
sub-steps, the light held over the frame (``gevsim.emulation.driver.substeps``: the pixel's fastest
noise path must be resolved for noise-event rates not to depend on the step, within ~10 %). This
script times that path (photoreceptor with every noise, DVS and gradient events on every sub-step)
and v2e's default noisy DVS (one ``generate_events`` per frame) alternately, chunk by chunk, on the
same input, and prints both at the frame step and at the sub-step::

    PYTHONPATH=.:/tmp/v2e_src:/tmp/v2edeps .venv/bin/python benchmarks/physics_valid_path.py \\
        [--sizes 346x260] [--threads 2] [--steps 20] [--repeat 3] [--inputs flicker_pan]

(v2e's source in /tmp/v2e_src and its extra imports in /tmp/v2edeps: ``benchmarks/README.md``,
"Rerun after issue 37's threading work".) Ratios are v2e's seconds over gevsim's for the same
simulated time (> 1: gevsim faster), min / median / max over the timed chunks.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numba
import numpy as np
from event_throughput import DN_FLOOR, Chunk, GevsimStages, V2e, inputs, spread

from gevsim.pixel import load_preset
from gevsim.pixel.noise import coarsest_step_s


def sub_stepped(stages: GevsimStages, c: Chunk, k: int) -> float:
    """Seconds for gevsim's photoreceptor, DVS and gradient over chunk ``c`` in ``k`` sub-steps per frame
    (the frame's photocurrent held), one frame at a time (a frame's sub-steps are one call)."""
    t_prev = float(c.t[0]) - float(c.t[1] - c.t[0])
    total = 0.0
    for current, t_end in zip(c.current, c.t):
        t = t_prev + (t_end - t_prev) * np.arange(1, k + 1) / k
        frames = np.broadcast_to(current, (k, *current.shape))
        tick = time.perf_counter()
        v = stages.pr.process(frames, t)
        stages.dvs.process(v, t)
        stages.grad.process(v, t)
        total += time.perf_counter() - tick
        t_prev = float(t_end)
    return total


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="346x260")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--steps", type=int, default=20, help="frames per chunk")
    ap.add_argument("--repeat", type=int, default=3, help="timed chunks (after one warm-up chunk)")
    ap.add_argument("--inputs", default="flicker_pan")
    args = ap.parse_args()
    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    import torch

    torch.set_num_threads(args.threads)
    noisy = load_preset("davis346")
    print(f"{args.threads} thread(s) each side; chunks of {args.steps} frames, {args.repeat} timed after a warm-up")
    for size in args.sizes.split(","):
        w, h = (int(x) for x in size.split("x"))
        for inp in inputs(args.inputs.split(","), h, w, args.steps, noisy, noisy, chunks=args.repeat + 1,
                          cache="/tmp/gevsim-bench-cache", office_spp=2):
            frame_gv, sub_gv = GevsimStages((h, w), noisy, seed=0, csdvs=False), None
            v2e = V2e(noisy=True, seed=0)
            rows: dict[str, list[float]] = {"gevsim, frame step": [], "gevsim, physics-valid sub-steps": [],
                                            "v2e noisy DVS": []}
            k = 1
            for j in range(args.repeat + 1):
                current, t = inp.chunk(j)
                if sub_gv is None:
                    limit = coarsest_step_s(noisy.photoreceptor, noisy.noise, float(current.max()))
                    k = 1 if limit is None else math.ceil(float(t[1] - t[0]) / limit - 1e-9)
                    sub_gv = GevsimStages((h, w), noisy, seed=0, csdvs=False)
                    print(f"{inp.name} {w}x{h}: frame {1e6 * float(t[1] - t[0]):.0f} us, coarsest step "
                          f"{1e6 * (limit or 0):.1f} us -> {k} sub-steps per frame")
                dn = current * np.float32(255.0 / float(current.max()))
                c = Chunk(current, t, dn, np.log(np.maximum(dn, np.float32(DN_FLOOR))))
                s_frame = _path_seconds(frame_gv, c)
                s_sub = sub_stepped(sub_gv, c, k)
                s_v2e = v2e.run(c)["v2e noisy"][0]
                if j:
                    rows["gevsim, frame step"].append(s_frame)
                    rows["gevsim, physics-valid sub-steps"].append(s_sub)
                    rows["v2e noisy DVS"].append(s_v2e)
            for label, secs in rows.items():
                print(f"  {label:34s} {statistics.median(secs):8.4f} s per chunk of {args.steps} frames")
            for label in ("gevsim, frame step", "gevsim, physics-valid sub-steps"):
                ratios = [v / g for g, v in zip(rows[label], rows["v2e noisy DVS"])]
                lo, med, hi = spread(ratios)
                print(f"  v2e / {label:28s} {lo:6.3f} / {med:6.3f} / {hi:6.3f} (min / median / max)")


def _path_seconds(stages: GevsimStages, c: Chunk) -> float:
    """Seconds of the davis346 path (photoreceptor, DVS, gradient) at the frame step."""
    return stages.run(c)["pixel + DVS + gradient"][0]


if __name__ == "__main__":
    main()
