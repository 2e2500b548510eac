"""Render time per basis image and per pose (all light groups) for each built-in scene.

Usage: python benchmarks/render_times.py [--spp N] [--width W --height H] [--repeat R]
Set GEVSIM_VARIANT=scalar_rgb (etc.) to time another variant. Nothing is cached.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from gevsim.render import MitsubaScene, builtin_scenes, load, override


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int)
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {platform.system()}")
    for name, path in builtin_scenes().items():
        m = override(load(path), spp=args.spp, width=args.width, height=args.height)
        scene = MitsubaScene(m)
        scene.set_pose(scene.pose_at(0.0))
        scene.set_groups({m.group_names[0]})
        scene.render()  # warm-up: JIT compilation on the LLVM/CUDA variants
        times = []
        for _ in range(args.repeat):
            for g in m.group_names:
                scene.set_groups({g})
                start = time.perf_counter()
                scene.render()
                times.append(time.perf_counter() - start)
        per_image = float(np.median(times))
        n_poses = len(scene.pose_times())
        print(f"{name:13s} {scene.variant.variant:12s} {m.render.width}x{m.render.height} {m.render.spp:3d} spp: "
              f"{per_image:.3f} s/basis image, {per_image * len(m.group_names):.3f} s/pose "
              f"({len(m.group_names)} groups), {n_poses} poses for {1e3 * m.duration_s:.0f} ms")


if __name__ == "__main__":
    main()
