"""Wall time of a study on 1 and 2 workers (alternating runs, fresh output folders, renders cached),
and whether every run gives the same numbers bit for bit.

    python benchmarks/study_parallel.py [experiments/demo.toml] [--rounds 2] [--cache .gevsim-cache]

Prints each run's wall and user CPU time, the median 1-worker / 2-worker ratio, and checks that
``results.json`` (timings aside) is identical across runs.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).parents[1]


def rows(folder: Path) -> str:
    return json.dumps([{k: v for k, v in r.items() if k != "seconds"}
                       for r in json.loads((folder / "results.json").read_text())])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", nargs="?", default=str(ROOT / "experiments" / "demo.toml"))
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--cache", default=str(ROOT / ".gevsim-cache"))
    args = parser.parse_args()
    walls: dict[int, list[float]] = {1: [], 2: []}
    results = set()
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.rounds):
            for workers in ((2, 1) if k % 2 == 0 else (1, 2)):
                out = Path(tmp) / f"w{workers}_{k}"
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                start = time.perf_counter()
                subprocess.run([sys.executable, "-m", "gevsim.cli", "study", args.config, "--out", str(out),
                                "--cache", args.cache, "--workers", str(workers), "-q"], check=True,
                               stdout=subprocess.DEVNULL)
                wall = time.perf_counter() - start
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                walls[workers].append(wall)
                results.add(rows(out))
                print(f"workers={workers} wall {wall:6.1f} s  user {after.ru_utime - before.ru_utime:6.1f} s",
                      flush=True)
    ratios = sorted(a / b for a, b in zip(walls[1], walls[2]))
    print(f"1 worker / 2 workers: {' '.join(f'{r:.2f}' for r in ratios)} (median {ratios[len(ratios) // 2]:.2f})")
    print("results identical across runs:", len(results) == 1)


if __name__ == "__main__":
    main()
