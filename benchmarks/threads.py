"""numba at 1 and 2 threads, with and without OpenMP spinning, on a quiet and on a loaded machine (issue 37, item 3).

    python benchmarks/threads.py [--sizes 96x72,346x260] [--steps 200] [--repeat 3] [--hogs 0,1]
                                 [--policies default,passive,spin10k] [--json OUT]

Each (load, policy) pair runs in a fresh child process, ``--repeat`` times, the policies alternating
(each in each place of the order in turn), because libgomp reads its wait policy once, when it loads. A child builds the davis346
pixel (photoreceptor with its full noise, mismatch and leak), DVS and gradient emulators per size,
warms them up on one chunk (numba's cache loads), then times ``--steps`` steps of 10 us per chunk,
threads alternating 1, 2, 2, 1, ... (4 chunks each). The input: a seeded random texture panning 1 px
per 50 steps under a 100 Hz lamp (+-30 %) at ~1 klux on the chip.

Policies: ``default`` (libgomp's own: no OMP_WAIT_POLICY, ~300,000 spins at each barrier; the child
loads libgomp before importing gevsim, which would set PASSIVE), ``passive`` (gevsim's default:
``OMP_WAIT_POLICY=PASSIVE``, threads sleep at once), ``spin10k`` (PASSIVE with
``GOMP_SPINCOUNT=10000``: spin ~0.1 ms, then sleep).

Load: ``--hogs N`` starts N busy Python loops (one core each) for the whole measurement of that load
(``0``: the machine as it is). The header prints the load average. Rows: per size, stage and policy,
the median seconds per chunk at 1 and 2 threads and their ratio (1 thread / 2 threads: above 1, two
threads are faster). Not a timed test.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).parents[1]
POLICIES = {
    "default": {},  # libgomp's default; OMP_WAIT_POLICY removed below
    "passive": {"OMP_WAIT_POLICY": "PASSIVE"},
    "spin10k": {"OMP_WAIT_POLICY": "PASSIVE", "GOMP_SPINCOUNT": "10000"},
}
STAGES = ("photoreceptor", "DVS", "gradient", "total")
THREAD_ORDER = (1, 2, 2, 1, 1, 2, 2, 1)


def child(sizes: list[tuple[int, int]], steps: int) -> None:
    """Run in a fresh process: times per chunk, printed as one JSON line."""
    if "OMP_WAIT_POLICY" not in os.environ:  # "default": libgomp loads before gevsim could set PASSIVE
        import numba

        @numba.njit(parallel=True)
        def _touch(n):
            s = 0.0
            for i in numba.prange(n):
                s += i
            return s

        _touch(10)
    import numba
    import numpy as np

    from gevsim.events import BrightnessEmulator, GradientEmulator
    from gevsim.pixel import Photoreceptor, load_preset

    preset = load_preset("davis346")
    out: dict = {"layer": None, "policy": os.environ.get("OMP_WAIT_POLICY"),
                 "spincount": os.environ.get("GOMP_SPINCOUNT"), "times": {}}
    for h, w in sizes:
        rng = np.random.default_rng(1)
        texture = rng.uniform(0.2, 1.0, (h, w + steps)).astype(np.float32)
        pr = Photoreceptor((h, w), params=preset.photoreceptor, noise=preset.noise, rng=rng)
        dvs = BrightnessEmulator((h, w), preset.events, rng=rng)
        grad = GradientEmulator((h, w), mismatch_sigma_ln=preset.events.threshold_mismatch_ln, rng=rng)
        times: dict = {f"{n}": {s: [] for s in STAGES} for n in (1, 2)}
        for k, threads in enumerate((1, *THREAD_ORDER)):  # the first chunk warms up, untimed
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            t = (k * steps + np.arange(1, steps + 1)) * 1e-5
            shift = (np.arange(steps) // 50) % w
            lamp = (1.0 + 0.3 * np.sin(2 * np.pi * 100.0 * t)).astype(np.float32)
            current = np.stack([texture[:, s:s + w] for s in shift]) * lamp[:, None, None] * np.float32(2e-12)
            tick = time.perf_counter()
            v = pr.process(current, t)
            a = time.perf_counter()
            dvs.process(v, t)
            b = time.perf_counter()
            grad.process(v, t)
            c = time.perf_counter()
            if k:
                row = times[f"{threads}"]
                for stage, seconds in zip(STAGES, (a - tick, b - a, c - b, c - tick)):
                    row[stage].append(seconds)
        out["times"][f"{w}x{h}"] = times
    out["layer"] = numba.threading_layer()
    print(json.dumps(out))


def run_child(policy: str, sizes: str, steps: int) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    env.update(POLICIES[policy])
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    done = subprocess.run([sys.executable, __file__, "--child", "--sizes", sizes, "--steps", str(steps)],
                          env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def measure(hogs: int, policies: list[str], sizes: str, steps: int, repeat: int) -> dict:
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(hogs)]
    try:
        time.sleep(1.0 if hogs else 0.0)
        load = os.getloadavg()[0]
        results: dict = {p: [] for p in policies}
        for r in range(repeat):  # each policy in each place of the order in turn
            for p in policies[r % len(policies):] + policies[:r % len(policies)]:
                results[p].append(run_child(p, sizes, steps))
        return {"hogs": hogs, "load_before": load, "load_after": os.getloadavg()[0], "results": results}
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


def report(m: dict, steps: int) -> list[dict]:
    rows = []
    print(f"\n## {m['hogs']} busy loop(s) beside it (load average {m['load_before']:.2f} -> {m['load_after']:.2f})")
    print("| size | stage | policy | 1 thread s | 2 threads s | 1 / 2 threads |\n| --- | --- | --- | --- | --- | --- |")
    first = next(iter(m["results"].values()))[0]
    for size in first["times"]:
        for stage in STAGES:
            for policy, runs in m["results"].items():
                one = statistics.median(x for r in runs for x in r["times"][size]["1"][stage])
                two = statistics.median(x for r in runs for x in r["times"][size]["2"][stage])
                rows.append({"hogs": m["hogs"], "size": size, "stage": stage, "policy": policy, "one_s": one,
                             "two_s": two, "ratio": one / two})
                print(f"| {size} | {stage} | {policy} | {one:.4f} | {two:.4f} | {one / two:.2f} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="96x72,346x260")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--hogs", default="0,1")
    parser.add_argument("--policies", default="default,passive,spin10k")
    parser.add_argument("--json")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    sizes = [(int(s.split("x")[1]), int(s.split("x")[0])) for s in args.sizes.split(",")]
    if args.child:
        child(sizes, args.steps)
        return
    policies = args.policies.split(",")
    print(f"# threads benchmark: {os.cpu_count()} CPUs, affinity {len(os.sched_getaffinity(0))}, "
          f"{args.steps} steps of 10 us per chunk, {args.repeat} children per policy, "
          f"{time.strftime('%Y-%m-%d %H:%M')}")
    rows, raw = [], []
    for hogs in (int(h) for h in args.hogs.split(",")):
        m = measure(hogs, policies, args.sizes, args.steps, args.repeat)
        layers = {r["layer"] for runs in m["results"].values() for r in runs}
        print(f"numba threading layer: {', '.join(sorted(layers))}")
        rows += report(m, args.steps)
        raw.append(m)
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "runs": raw}, indent=1))


if __name__ == "__main__":
    main()
