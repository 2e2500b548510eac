"""Render convergence: one-pass light groups vs one render per group, and time to the noise target.

For each built-in scene (first pose), side by side in one run:

1. both paths render the same batches (``--spp`` samples in the fixed mode's batches, same seeds):
   seconds, samples per second, and the achieved p99 ln error (flicker metric),
   so "equal noise" is measured, not assumed;
2. the one-pass path renders to the scene's default noise target (``noise_target_ln =
   "auto"``, capped by its ``max_spp``): spp reached, seconds, and the p99 error;
   the per-group path's time to the same spp is projected from the ratio in 1.

Usage: python benchmarks/render_convergence.py [--width 346 --height 260] [--spp 256] [--scenes office,...]
Nothing is cached.
"""

from __future__ import annotations

import argparse
import platform

from gevsim.render import MitsubaScene, builtin_scenes, load, override
from gevsim.render.basis import quality_request, render_pose
from gevsim.render.convergence import mixture_weights
from gevsim.render.quality import resolve_target


def fixed(scene: MitsubaScene, mixtures, *, spp: int, one_pass: bool):
    """Render ``spp`` samples in the fixed mode's batches; (seconds, p99 ln error)."""
    request = quality_request(override(scene.manifest, spp=spp).render, mixtures, None)
    _, _, _, report = render_pose(scene, request, one_pass=one_pass)
    return report.seconds, report.se_ln_percentiles["p99"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=346)
    ap.add_argument("--height", type=int, default=260)
    ap.add_argument("--spp", type=int, default=256, help="samples per pixel of the side-by-side comparison")
    ap.add_argument("--scenes", help="comma-separated scene names (default: every built-in scene)")
    args = ap.parse_args()
    names = args.scenes.split(",") if args.scenes else list(builtin_scenes())
    print(f"machine: {platform.machine()}, {platform.system()}; {args.width}x{args.height}")
    print(f"{'scene':13s} {'K':>2s} | {'one-pass s':>10s} {'per-group s':>11s} {'ratio':>6s} {'Msamples/s':>10s} "
          f"{'p99 1-pass':>10s} {'p99 per-grp':>11s} | {'target':>7s} {'spp':>6s} {'s':>7s} {'p99':>7s} "
          f"{'stop':>9s} {'per-group s (proj.)':>19s}")
    for name in names:
        m = override(load(name), width=args.width, height=args.height)
        scene = MitsubaScene(m)
        scene.set_pose(scene.pose_at(0.0))
        mixtures = mixture_weights([scene.group(g).waveform.value_range() for g in m.group_names])
        scene.render_groups(spp=4, seed=0)  # compile both kernels once
        scene.render_groups(spp=4, seed=0, one_pass=False)
        t_one, e_one = fixed(scene, mixtures, spp=args.spp, one_pass=True)
        t_per, e_per = fixed(scene, mixtures, spp=args.spp, one_pass=False)
        rate = args.width * args.height * args.spp / t_one / 1e6
        request = quality_request(m.render, mixtures, resolve_target(m.render))
        _, _, _, report = render_pose(scene, request)
        projected = report.seconds * t_per / t_one
        print(f"{name:13s} {len(m.group_names):2d} | {t_one:10.2f} {t_per:11.2f} {t_per / t_one:6.2f} {rate:10.2f} "
              f"{e_one:10.4f} {e_per:11.4f} | {request['target_ln']:7.4f} {report.spp:6d} {report.seconds:7.1f} "
              f"{report.se_ln:7.4f} {report.stopped_by:>9s} {projected:19.1f}", flush=True)


if __name__ == "__main__":
    main()
