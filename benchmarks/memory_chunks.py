"""Chunks sized by memory (issue 37, item 4): peak memory of 1280x720 runs, and speed against the chunk size.

Usage: python benchmarks/memory_chunks.py [--durations 0.01 0.05] [--fixed 256] [--speed 3 12 48] [--work DIR]

``--durations``: ``gevsim emulate`` of the office scene rendered at 1280x720 with 1 sample per pixel (a static
camera: one pose, rendered once into ``DIR/cache`` by a warm-up run that is not measured), the davis346 sensor,
all four emulators, the default 10 ms burn-in, each in a child process that prints its peak resident memory
(VmHWM, Linux) and wall time; chunk_steps unset (from the memory budget). ``--fixed N`` adds one run of the first
duration with ``chunk_steps = N`` (256: the former default). The events of every run are compared bit for bit.

``--speed N...``: in this process, on the basis loaded once, 4 ms runs at 1280x720 from a cold start (no settling,
no stationary DVS levels, no burn-in: at 1280x720 they cost more than the 4 ms themselves) with each ``chunk_steps``
in turn, ``--rounds`` times over (ABAB...), printing each run's wall time, its summary's stages
(:attr:`gevsim.emulation.summary.RunSummary.stage_s`), how much of the run they cover, and their stepping (mix,
photoreceptor, emulators and readout) per pixel-step.
"""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # h5_digest: the pinned-output tests' hash of a whole file

#: The child: `gevsim ARGS`, then its own peak resident memory (KiB, VmHWM of /proc/self/status) on the last line.
CHILD = ("import re, sys; from gevsim.cli import main; rc = main(sys.argv[1:]); "
         "print(re.search(r'VmHWM:\\s*(\\d+)', open('/proc/self/status').read()).group(1)); sys.exit(rc)")
CONFIG = """[emulation]
scene = "office"
duration_s = {duration}
{extra}
[render]
width = 1280
height = 720
spp = 1
"""


def emulate(work: Path, name: str, duration: float, extra: str = "") -> tuple[float, float, Path]:
    """One ``gevsim emulate`` in a child process: (peak MiB, wall s, the file)."""
    cfg = work / f"{name}.toml"
    cfg.write_text(CONFIG.format(duration=duration, extra=extra))
    out = work / f"{name}.h5"
    tick = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CHILD, "emulate", str(cfg), "--out", str(out), "--cache",
                           str(work / "cache"), "-q"], capture_output=True, text=True)
    wall = time.perf_counter() - tick
    if done.returncode:
        raise SystemExit(f"{name}: exit {done.returncode}\n{done.stderr[-2000:]}")
    return int(done.stdout.split()[-1]) / 1024, wall, out


def peaks(work: Path, durations: list[float], fixed: int | None) -> None:
    from test_pinned_outputs import h5_digest  # type: ignore[import-not-found]

    emulate(work, "warm", 0.001, "burn_in_s = 0.0")  # renders the basis into the cache
    runs = [(f"{d * 1e3:g} ms, chunk_steps from the budget", emulate(work, f"auto_{d:g}", d)) for d in durations]
    if fixed:
        runs.append((f"{durations[0] * 1e3:g} ms, chunk_steps = {fixed}",
                     emulate(work, f"fixed_{fixed}", durations[0], f"chunk_steps = {fixed}")))
    print("| run | peak RSS (MiB) | wall (s) |\n| --- | --- | --- |")
    for label, (peak, wall, _) in runs:
        print(f"| {label} | {peak:.0f} | {wall:.0f} |")
    if fixed:
        same = h5_digest(runs[0][1][2]) == h5_digest(runs[-1][1][2])
        print(f"events and file of the budget's chunks and of chunk_steps = {fixed} identical: {same}")


def speed(work: Path, sizes: list[int], rounds: int) -> None:
    from gevsim.emulation import EmulationConfig, prepare, run

    base = EmulationConfig(scene="office", duration_s=0.004, cold_start=True, render=dict(width=1280, height=720, spp=1))
    setup = prepare(base, cache_dir=work / "cache")
    print("| chunk_steps | wall (s) | stages / wall | " + " | ".join(("mix", "photoreceptor", "emulators", "readout",
                                                                      "other stages", "stepping ns/pixel-step")) + " |")
    print("| --- " * 9 + "|")
    for r in range(rounds):
        for n in sizes:
            config = dataclasses.replace(base, chunk_steps=n)
            tick = time.perf_counter()
            s = run(config, work / "speed.h5", setup=setup)
            wall = time.perf_counter() - tick
            st = s.stage_s
            emulators = sum(st[e] for e in s.event_s)
            stepping = st["mix"] + st["photoreceptor"] + emulators + st["readout"]
            ns = stepping / (s.steps * s.width * s.height) * 1e9
            print(f"| {n} (round {r + 1}) | {wall:.1f} | {sum(st.values()) / wall:.4f} | {st['mix']:.2f} | "
                  f"{st['photoreceptor']:.2f} | {emulators:.2f} | {st['readout']:.2f} | "
                  f"{sum(st.values()) - stepping:.2f} | {ns:.1f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--durations", type=float, nargs="*", default=[0.01, 0.05])
    ap.add_argument("--fixed", type=int, default=None, help="also one run with this chunk_steps (e.g. 256)")
    ap.add_argument("--speed", type=int, nargs="*", default=[], help="chunk_steps to time side by side")
    ap.add_argument("--rounds", type=int, default=3, help="rounds of --speed")
    ap.add_argument("--work", type=Path, default=None, help="folder for the cache and files (default: a temporary one)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        if args.durations:
            peaks(work, args.durations, args.fixed)
        if args.speed:
            speed(work, args.speed, args.rounds)


if __name__ == "__main__":
    main()
