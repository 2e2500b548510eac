"""Emulate a built-in scene with a DAVIS346 and read the events and the ground truth back.

Run from the repository root: ``python examples/emulate_scene.py [OUT_DIR]`` (default ``out/examples``).
A small, draft-quality render (64x48, 16 samples per pixel) keeps it to seconds; drop the ``render``
overrides for the scene's own resolution and noise target.
"""

import sys
from pathlib import Path

from gevsim.emulation import EmulationConfig, run
from gevsim.io import EventReader

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/examples")
out.mkdir(parents=True, exist_ok=True)
config = EmulationConfig(scene="office", sensor="davis346", emulators=("dvs", "gradient"), seed=1,
                         duration_s=0.01, frame_rate_hz=1000.0, render={"width": 64, "height": 48, "spp": 16})
summary = run(config, out / "office.h5", cache_dir=out / "cache")
print(f"{summary.counts['events']} DVS and {summary.counts['gradient_events']} gradient events "
      f"in {summary.duration_s * 1e3:.0f} ms")

with EventReader(out / "office.h5") as r:
    events = r.read("events")  # structured array: x, y (int16), t (int64 us), p
    frames, t_us = r.frames("log_photocurrent")  # noise-free ln(photocurrent) at each frame time
    depth, _ = r.frames("depth")  # m, z in the camera frame
    print(f"{len(events)} events, {len(frames)} ground-truth frames of {r.width}x{r.height}, "
          f"depth {depth.min():.2f}-{depth.max():.2f} m")
