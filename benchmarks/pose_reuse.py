"""Moving scenes: reuse of converged radiance across poses against a render per pose (brute force).

For a scene and size, renders the basis with ``[render] reuse = "none"`` (every
pose alone) and with each reuse method that applies (rotation at several cell
counts per pixel), side by side in one process, from empty caches; then runs
the same ideal-sensor emulation on each basis and compares DVS and gradient
event rates. Prints a Markdown table: wall time, poses rendered / reused, p99 ln
error, rates and their ratio to brute force.

    python benchmarks/pose_reuse.py --scene scenes/office_pan.toml --size 64x48
    python benchmarks/pose_reuse.py --scene scenes/office_pan.toml --size 346x260 --no-brute --poses 3
    python benchmarks/pose_reuse.py --scene scenes/office_dolly.toml --reuse parallax --subs 3
    python benchmarks/pose_reuse.py --scene scenes/office_dolly.toml --reuse parallax --subs 3 --sampling adaptive

``--no-brute --poses N`` times N brute-force poses only (their mean time per pose
scales to the whole sequence) where the full brute force is unaffordable.
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from gevsim.render import rotation
from gevsim.render.basis import render_basis
from gevsim.render.manifest import load
from gevsim.render.scene import MitsubaScene


def basis_for(manifest, reuse: str, cache: Path, sub: int | None = None, times=None, sampling: str = "uniform"):
    r = dataclasses.replace(manifest.render, reuse=reuse, sampling=sampling)
    scene = MitsubaScene(dataclasses.replace(manifest, render=r))
    old = rotation.SUB
    rotation.SUB = sub or old
    try:
        start = time.perf_counter()
        basis = render_basis(scene, cache_dir=cache, times_s=times)
        return basis, time.perf_counter() - start
    finally:
        rotation.SUB = old


def rates(scene_path: str, size: tuple[int, int], cache: Path, reuse: str, sub: int | None, out: Path,
          overrides: str) -> dict:
    """Ideal-sensor DVS and gradient rates (events / s / px) of an emulation on the cached basis."""
    from gevsim.emulation.config import load_config
    from gevsim.emulation.driver import run

    cfg = out / f"{reuse}{sub or ''}.toml"
    cfg.write_text(f'[emulation]\nscene = "{Path(scene_path).resolve()}"\nsensor = "ideal"\nseed = 1\n'
                   f'emulators = ["dvs", "gradient"]\nstep_s = 2e-5\n[render]\nwidth = {size[0]}\n'
                   f'height = {size[1]}\nreuse = "{reuse}"\n{overrides}')
    old = rotation.SUB
    rotation.SUB = sub or old
    try:
        summary = run(load_config(cfg), out / f"{reuse}{sub or ''}.h5", cache_dir=cache)
    finally:
        rotation.SUB = old
    px = size[0] * size[1]
    return {k: v / px for k, v in summary.rates_hz.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="scenes/office_pan.toml")
    ap.add_argument("--size", default="64x48")
    ap.add_argument("--reuse", default="rotation", help="the reuse method to compare with brute force")
    ap.add_argument("--subs", default="1,2,3", help="cells per pixel of the reference render")
    ap.add_argument("--spp", type=int, default=None, help="fixed spp instead of the scene's noise target")
    ap.add_argument("--no-brute", action="store_true", help="time only --poses brute-force poses")
    ap.add_argument("--poses", type=int, default=3)
    ap.add_argument("--no-events", action="store_true")
    ap.add_argument("--sampling", default="uniform", choices=("uniform", "adaptive"),
                    help="[render] sampling of the reuse method (brute force stays uniform: today's renderer)")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    m = load(args.scene)
    extra = {"width": w, "height": h}
    overrides = ""
    if args.spp:
        extra.update(spp=args.spp, noise_target_ln=None)
        overrides = f"spp = {args.spp}\n"
    m = dataclasses.replace(m, render=dataclasses.replace(m.render, **extra))
    tmp = Path(tempfile.mkdtemp(prefix="pose_reuse_"))
    rows = []
    try:
        subs = [int(s) for s in args.subs.split(",") if s]
        methods = [(args.reuse, s) for s in subs] + [("none", None)]
        results = {}
        for reuse, sub in methods:
            cache = tmp / f"cache_{reuse}{sub or ''}"
            times = None
            if reuse == "none" and args.no_brute:
                scene = MitsubaScene(m)
                all_times = scene.pose_times()
                times = all_times[np.linspace(0, len(all_times) - 1, args.poses).astype(int)]
            sampling = "uniform" if reuse == "none" else args.sampling
            basis, seconds = basis_for(m, reuse, cache, sub, times, sampling)
            q = basis.noise_summary()
            if times is not None:
                seconds *= len(all_times) / len(times)
            r = None if args.no_events or times is not None else rates(
                args.scene, (w, h), cache, reuse, sub, tmp, overrides + f'sampling = "{sampling}"\n')
            rendered = int((basis.render_s > 0).sum())
            results[(reuse, sub)] = (seconds, len(basis.times_s), rendered, q, r, times is not None)
        brute = results[("none", None)]
        for (reuse, sub), (seconds, poses, rendered, q, r, scaled) in results.items():
            label = f"{reuse}" + (f" (sub {sub})" if sub else "") + (f", {args.sampling}" if reuse != "none" else "") \
                + (" [scaled]" if scaled else "")
            ratio = brute[0] / seconds
            row = [label, f"{seconds:.1f}", f"{ratio:.1f}x", f"{rendered} / {poses - rendered}",
                   f"{q['spp_max']}", f"{q['se_ln']['p99']:.4f}"]
            for stream in ("events", "gradient_events"):
                if r is None:
                    row.append("-")
                else:
                    base = brute[4][stream] if brute[4] else float("nan")
                    row.append(f"{r[stream]:.1f} ({r[stream] / base:.3f})")
            rows.append(row)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"\n{args.scene} {w}x{h}, " + (f"{args.spp} spp" if args.spp else "noise target"))
    print("| method | wall s | speed-up | rendered / reused poses | spp | p99 ln error | DVS ev/px/s (vs brute) "
          "| gradient ev/px/s (vs brute) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
