"""Noise-event rates against the time step on static scenes (issue 22), down to 2.5 us.

The same runs as ``tests/pixel/test_step_independence.py`` (davis346 noise; DVS and CSDVS at a
0.02 ln threshold, the preset's 0.2 ln being leak only; gradient with the paper's thresholds),
24x32 px, 40 ms of which the first 5 are dropped.

    .venv/bin/python benchmarks/step_convergence.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "pixel"))
from test_step_independence import SHAPE, noise_rates, textured_lux  # noqa: E402


def main() -> None:
    scenes = {"uniform 10 lux": np.full(SHAPE, 10.0), "textured 10 lux": textured_lux(10.0),
              "uniform 1000 lux": np.full(SHAPE, 1000.0)}
    steps = (40e-6, 20e-6, 10e-6, 5e-6, 2.5e-6)
    print("| scene | stream | " + " | ".join(f"{s * 1e6:g} us" for s in steps) + " | max/min 20-5 us |")
    print("|---" * (len(steps) + 3) + "|")
    for name, lux in scenes.items():
        rows = [noise_rates(lux, s) for s in steps]
        for stream in rows[0]:
            r = [row[stream] for row in rows]
            print(f"| {name} | {stream} | " + " | ".join(f"{x:.2f}" for x in r) + f" | {max(r[1:4]) / max(min(r[1:4]), 1e-9):.3f} |")


if __name__ == "__main__":
    main()
