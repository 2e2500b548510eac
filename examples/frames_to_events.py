"""Frame mode: DVS and gradient events from a sequence of grayscale frames (the paper's setting).

Run: ``python examples/frames_to_events.py [OUT_DIR]``. A bright bar moves across a textured
background; the events are written to an emulation file with the frames as ground truth and
converted for tonic.
"""

import sys
from pathlib import Path

import numpy as np

from gevsim.emulation import emulate_frames, run_frames
from gevsim.io import to_tonic, tonic_sensor_size

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/examples")
out.mkdir(parents=True, exist_ok=True)
h, w, n = 48, 64, 20
y, x = np.mgrid[0:h, 0:w]
frames = np.array([np.clip(0.3 + 0.1 * np.sin(x / 4.0) + 0.5 * (np.abs(x - 5 - 2 * k) < 3), 0, 1)
                   for k in range(n)])
t_s = np.arange(n) / 1000.0  # 1 kHz frames
events = emulate_frames(frames, t_s, rng=np.random.default_rng(0))
print({name: len(ev) for name, ev in events.items()})
run_frames(frames, t_s, out / "bar.h5", seed=0)  # the same, into an emulation file

dvs = to_tonic(events["events"])  # p: 0 OFF, 1 ON, for tonic's transforms
print("tonic sensor size", tonic_sensor_size(w, h, events["events"]), "first events", dvs[:3])
