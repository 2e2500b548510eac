"""How often a dataset made in a Dask worker thread lays out its HDF5 shards at other byte offsets than a
serial run (issue 37: the events and every stored value are the same; the bytes differed in about one run
in four to eight at stop 42, one in 26 at stop 44).

A serial reference of the tests' 3-sequence dataset (tests/experiments/test_dataset.py), then RUNS runs, each
on a fresh one-worker threaded LocalCluster (``make_executor("dask", workers=1, processes=False)``); each run's
shards are compared byte for byte with the reference's. ``NOPROFILE=1`` switches Dask's statistical profiler
off (a thread that holds the worker's frames while it samples them).

    .venv/bin/python benchmarks/layout_determinism.py [RUNS]
"""

from __future__ import annotations

import hashlib
import logging
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests" / "experiments"))
sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))

from test_dataset import write_config  # type: ignore[import-not-found]  # noqa: E402

from gevsim.experiments.dataset import generate, load_dataset_config  # noqa: E402
from gevsim.experiments.executors import make_executor  # noqa: E402


def raw(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*.h5"))}


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 8
    logging.disable(logging.WARNING)
    if os.environ.get("NOPROFILE"):
        import dask

        dask.config.set({"distributed.worker.profile.enabled": False})
    base = Path(tempfile.mkdtemp())
    config = load_dataset_config(write_config(base))
    cache = base / "cache"
    generate(config, base / "ref", cache_dir=cache)
    ref = raw(base / "ref")
    differ = 0
    for k in range(runs):
        with make_executor("dask", workers=1, processes=False) as client:
            out = base / f"run{k}"
            generate(config, out, cache_dir=cache, executor=client)
        bad = [name for name in ref if raw(out).get(name) != ref[name]]
        differ += bool(bad)
        print(k, "differs:" if bad else "same", *bad, flush=True)
    print(f"{differ} of {runs} runs laid out differently ({base})")


if __name__ == "__main__":
    main()
