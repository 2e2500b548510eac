"""``gevsim dataset --part I/N`` and ``--merge``: a dataset made by an array job, one part per task
(:mod:`gevsim.experiments.parts`; docs/cluster.md).

Part ``I`` of ``N`` makes the sequences ``j`` with ``j % N == I`` that ``OUT`` does not hold finished, in
``OUT.parts/I-of-N`` (the same shards, markers and EVREAL folders as a run into ``OUT``: every sequence draws
from its own seed, so a sequence made in a part is the one a single run makes, bit for bit). The part that
finds every sequence finished when it ends merges them all into ``OUT`` and writes ``OUT/dataset.json``.
"""

from __future__ import annotations

import concurrent.futures as cf
import os
from collections.abc import Callable
from pathlib import Path

from gevsim.experiments.dataset import DatasetConfig, _generate, dataset_work, finished, write_index
from gevsim.experiments.parts import MERGE_WAIT_S, Part, check_out, merge_parts, owned, part_folder, unfinished
from gevsim.io import exclusive, sweep_stale
from gevsim.io.atomic import FolderBusy


def generate_part(config: DatasetConfig, out_dir: str | os.PathLike, part: Part, *,
                  executor: cf.Executor | None = None, cache_dir: str | os.PathLike | None = None,
                  progress: Callable[[int, int], None] | None = None, wait_s: float = MERGE_WAIT_S) -> dict:
    """Make part ``part`` of the dataset ``out_dir`` in its part folder; merge every part into ``out_dir`` when
    none is left unfinished (waiting up to ``wait_s`` for a part that is still recording its folder).

    Returns :func:`gevsim.experiments.dataset.generate`'s summary of the part (``out`` is its folder; the
    sequences ``OUT`` already held count as skipped), with ``merge``: ``"complete"`` (this part merged
    them all), ``"waiting"`` (``unfinished`` sequences are not finished yet: the last part merges),
    ``"merged"`` (another part merged this one), ``"busy"`` (another gevsim run holds ``OUT``: a later run or
    ``--merge`` merges) or ``"incomplete"`` (merged, but some part folder was busy beyond ``wait_s``).
    """
    out = Path(out_dir)
    check_out(out, "dataset")  # a folder the merge could not write into: refused before any work
    folder = part_folder(out, part)
    mine = list(range(part.index, config.sequences, part.count))
    if owned(out, "dataset"):  # what an earlier merge moved into OUT is not made again
        digests: dict = {}
        mine = [j for j in mine if finished(config, out, j, digests=digests) is None]
    taken = len(range(part.index, config.sequences, part.count))
    with exclusive(folder, what="dataset", kind="dataset"):
        summary = _generate(config, folder, executor=executor, indices=mine, cache_dir=cache_dir,
                            progress=progress, index=False)
    summary.update(sequences=taken, skipped=summary["skipped"] + taken - len(mine), part=str(part))
    work = dataset_work(config)
    left = unfinished(out, work)
    if left:
        return {**summary, "merge": "waiting", "unfinished": left}
    if not folder.exists():
        return {**summary, "merge": "merged", "unfinished": 0}
    try:
        merged = merge(config, out, wait_s=wait_s)
    except FolderBusy:
        return {**summary, "merge": "busy", "unfinished": 0}
    return {**summary, "merge": "complete" if merged["complete"] else "incomplete", "unfinished": merged["missing"]}


def merge(config: DatasetConfig, out_dir: str | os.PathLike, *, wait_s: float = 0.0) -> dict:
    """Move what the part folders finished into ``out_dir`` and write its ``dataset.json``; nothing is made.
    Returns ``moved`` (sequences moved in), ``busy`` (part folders another process held), ``complete`` and
    ``missing`` (sequences finished nowhere in ``out_dir``)."""
    out = Path(out_dir)
    with exclusive(out, what="dataset", kind="dataset"):
        sweep_stale(out)
        merged = merge_parts(out, dataset_work(config), wait_s=wait_s)
        records = write_index(config, out)
    missing = config.sequences - len(records)
    return {"out": str(out), "moved": merged["moved"], "busy": merged["busy"], "complete": not missing,
            "missing": missing, "sequences": config.sequences}
