"""Wall time of the quick commands (``gevsim --help``, ``scenes``, ``presets``, ``info``), optionally side by side
with an earlier commit (issue 37, item 5).

    python benchmarks/startup.py [--against REV] [--runs 5] [--commands=--help,scenes,presets,info]

Each command runs as ``python -m gevsim.cli COMMAND`` in a fresh process, ``--runs`` times per tree,
the trees alternating (ABAB...), output discarded; the table gives the median and the range. With
``--against REV`` the files of that commit (``git archive``) are unpacked into a temporary folder and
run by the same interpreter (so the same installed libraries and numba cache folder layout), and the
last column is the median ratio REV / this tree. Also prints which heavy libraries each command of this
tree imports. Not a timed test.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).parents[1]
HEAVY = ("matplotlib", "colour", "mitsuba", "drjit", "numba", "h5py", "scipy", "OpenEXR")
PROBE = """
import sys, runpy
sys.argv = ["gevsim"] + sys.argv[1:]
try:
    runpy.run_module("gevsim.cli", run_name="__main__")
except SystemExit:
    pass
sys.stderr.write("HEAVY " + " ".join(sorted({m.split(".")[0] for m in sys.modules} & set(HEAVY))) + "\\n")
""".replace("HEAVY)", f"{HEAVY!r})")


def wall(tree: Path, command: str) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "gevsim.cli", command], cwd=tree, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=True)
    return time.perf_counter() - start


def heavy(tree: Path, command: str) -> str:
    done = subprocess.run([sys.executable, "-c", PROBE, command], cwd=tree, capture_output=True, text=True)
    line = [x for x in done.stderr.splitlines() if x.startswith("HEAVY")]
    return line[-1][6:] if line else "?"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", metavar="REV", help="an earlier commit to time side by side")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--commands", default="--help,scenes,presets,info")
    args = parser.parse_args()
    commands = args.commands.split(",")
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"this tree": ROOT}
        if args.against:
            before = Path(tmp) / "before"
            before.mkdir()
            archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.against], capture_output=True,
                                     check=True).stdout
            subprocess.run(["tar", "-x", "-C", str(before)], input=archive, check=True)
            trees = {args.against: before, "this tree": ROOT}
        for tree in trees.values():  # warm the file cache and numba's cache once per tree
            for command in commands:
                wall(tree, command)
        times: dict = {(t, c): [] for t in trees for c in commands}
        for r in range(args.runs):
            for name in (list(trees) if r % 2 == 0 else list(trees)[::-1]):
                for command in commands:
                    times[name, command].append(wall(trees[name], command))
        print(f"# python -m gevsim.cli COMMAND, median (min-max) of {args.runs} runs, {time.strftime('%Y-%m-%d')}")
        head = " | ".join(f"{t} s" for t in trees)
        print(f"| command | {head} |" + (f" {args.against} / this tree |" if args.against else "")
              + " heavy imports (this tree) |")
        print("| --- " * (len(trees) + 2 + bool(args.against)) + "|")
        for command in commands:
            cells = []
            for name in trees:
                t = times[name, command]
                cells.append(f"{statistics.median(t):.2f} ({min(t):.2f}-{max(t):.2f})")
            ratio = ""
            if args.against:
                old, new = (statistics.median(times[t, command]) for t in (args.against, "this tree"))
                ratio = f" {old / new:.1f}x |"
            print(f"| `{command}` | {' | '.join(cells)} |{ratio} {heavy(ROOT, command) or 'none'} |")


if __name__ == "__main__":
    main()
