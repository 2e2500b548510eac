"""Running a study: one job per (run, repeat) through an executor, then the repeats aggregated.

The study config and its runs are :mod:`gevsim.experiments.study`; a job is
:func:`gevsim.experiments.repeat.execute_repeat`; the aggregation of a run's
repeats into a row with intervals is :mod:`gevsim.experiments.aggregate`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from concurrent.futures import Executor
from pathlib import Path

import numpy as np

from gevsim.errors import ConfigError, suggest
from gevsim.experiments.executors import run_all
from gevsim.experiments.parts import MERGE_WAIT_S, Part, Work, check_out, merge_parts, owned, part_folder, unfinished
from gevsim.experiments.study import Study, flicker_group, run_config, run_emulators, run_id, run_scene
from gevsim.io import atomic_path, exclusive, sweep_stale
from gevsim.io.atomic import FolderBusy

__all__ = ["check_study_scenes", "collect", "collect_variations", "merge_study", "run_study", "run_study_part"]


def _prerender(study: Study, runs: list[dict], cache_dir: str | os.PathLike) -> None:
    """Render (or find in the cache) every basis the runs need, here, once: workers then only load them."""
    from gevsim.emulation import prepare

    seen = set()
    for params in runs:
        cfg = run_config(study, params)
        key = json.dumps([cfg.scene, cfg.render, cfg.sensor, cfg.thresholds_ln, cfg.sensor_overrides],
                         sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            prepare(cfg, cache_dir=cache_dir)


def run_study(study: Study, out: str | os.PathLike, *, cache_dir: str | os.PathLike | None = None,
              executor: Executor | None = None, progress: Callable[[int, int], None] | None = None,
              keep_files: bool = False) -> list[dict]:
    """Run (or resume) every repeat of every run of a study into ``out``; returns one result row per
    run (sweep order), with intervals over its repeats (:mod:`gevsim.experiments.aggregate`).

    One job per (run, repeat) (:func:`gevsim.experiments.repeat.execute_repeat`); finished jobs
    (``runs/<id>/r<k>.json``) are skipped, so interrupted studies resume and a study given more
    repeats runs only the new ones. ``executor`` None runs the jobs here, one after another; an
    executor (:func:`gevsim.experiments.executors.make_executor`) runs them in its workers, one numba
    thread each, after the bases are rendered here once into ``cache_dir`` (default
    ``out/render-cache``). The numbers do not depend on the executor. ``progress(done, total)``
    counts jobs. One study at a time per ``out``: a second one (another process) is refused with a
    :class:`~gevsim.errors.ConfigError` naming the folder (:func:`gevsim.io.exclusive`). What ``--part``
    runs finished beside it (``OUT.parts``, :mod:`gevsim.experiments.parts`) is merged in first.
    """
    out = Path(out)
    with exclusive(out, what="study", kind="study"):  # one study at a time per folder: a second one is refused
        rids, jobs = study_jobs(study)
        merge_parts(out, study_work(jobs))
        _run_jobs(study, out, jobs, cache_dir=cache_dir, executor=executor, progress=progress,
                  keep_files=keep_files)
        return collect(study, out, rids=rids)


def study_jobs(study: Study) -> tuple[list[str], list[tuple[dict, str, int]]]:
    """The sweep's run ids and every job (run parameters, run id, repeat) in their fixed order: each sweep
    run's repeats, then those of the runs around the headline that the sweep does not hold."""
    runs = study.runs()
    rids = [run_id(study, p) for p in runs]  # once per run: it hashes every file of the scene
    jobs = [(p, rid, r) for p, rid in zip(runs, rids) for r in range(study.base["repeats"])]
    seen = {(rid, r) for _, rid, r in jobs}
    for v in study.variations():  # the runs around the headline (a trade-off setting may be a sweep run)
        rid = run_id(study, v.params)
        jobs += [(v.params, rid, r) for r in range(v.repeats) if (rid, r) not in seen]
        seen.update((rid, r) for r in range(v.repeats))
    return rids, jobs


def study_work(jobs: list[tuple[dict, str, int]]) -> Work:
    """A study's jobs as the work a merge of ``--part`` folders moves (:mod:`gevsim.experiments.parts`); a
    part's render cache goes with its emptied folder."""
    from gevsim.experiments.repeat import STRIP_FILE, finished_repeat, repeat_paths

    def files(k: int) -> tuple[str, ...]:
        marker, arrays, folder = repeat_paths("", jobs[k][1], jobs[k][2])
        strip = (str(marker.parent / STRIP_FILE),) if jobs[k][2] == 0 else ()  # repeat 0 draws the run's events
        return (str(folder), str(arrays), *strip, str(marker))

    return Work("study", len(jobs), lambda folder, k: finished_repeat(folder, jobs[k][1], jobs[k][2]) is not None,
                files, scratch=("render-cache",))


def _run_jobs(study: Study, out: Path, jobs: list, *, cache_dir, executor, progress, keep_files) -> int:
    """Run the ``jobs`` not finished in ``out`` (locked by the caller); returns how many ran."""
    from gevsim.experiments import repeat as rep

    (out / "runs").mkdir(parents=True, exist_ok=True)
    sweep_stale(out)  # what killed runs left half-written (stages nobody holds)
    todo = [(p, rid, r) for p, rid, r in jobs if rep.finished_repeat(out, rid, r) is None]
    total, done = len(jobs), len(jobs) - len(todo)
    kwargs: dict = {"keep_files": keep_files}
    if executor is not None:
        cache_dir = out / "render-cache" if cache_dir is None else cache_dir
        if todo:
            _prerender(study, [p for p, _, _ in todo], cache_dir)
        kwargs["threads"] = 0  # numba threads as the executor set them: floor(cores / workers)
    cache = None if cache_dir is None else str(cache_dir)
    calls = [((study, p, r, str(out)), {**kwargs, "rid": rid, "cache_dir": cache}) for p, rid, r in todo]
    run_all(rep.execute_repeat, calls, executor=executor, progress=progress, done=done, total=total)
    return len(todo)


def run_study_part(study: Study, out: str | os.PathLike, part: Part, *, cache_dir: str | os.PathLike | None = None,
                   executor: Executor | None = None, progress: Callable[[int, int], None] | None = None,
                   keep_files: bool = False, wait_s: float = MERGE_WAIT_S) -> tuple[list[dict] | None, dict]:
    """Run part ``part`` of a study's jobs (the ``k``-th with ``k % N == I``) that ``out`` does not hold finished,
    in ``OUT.parts/I-of-N``; when no job is left unfinished, merge every part into ``out`` and collect it.

    Returns the result rows (None unless this part merged the study) and ``jobs`` (this part's), ``made``,
    ``unfinished`` (jobs of the study) and ``merge`` (as :func:`gevsim.experiments.dataset_parts.generate_part`'s).
    """
    out = Path(out)
    check_out(out, "study")  # a folder the merge could not write into: refused before any work
    folder = part_folder(out, part)
    rids, jobs = study_jobs(study)
    work = study_work(jobs)
    mine = list(range(part.index, len(jobs), part.count))
    taken = len(mine)
    if owned(out, "study"):  # what an earlier merge moved into OUT is not run again
        mine = [k for k in mine if not work.finished(out, k)]
    with exclusive(folder, what="study", kind="study"):
        made = _run_jobs(study, folder, [jobs[k] for k in mine], cache_dir=cache_dir, executor=executor,
                         progress=progress, keep_files=keep_files)
    info = {"jobs": taken, "made": made, "out": str(folder), "part": str(part), "unfinished": unfinished(out, work)}
    if info["unfinished"]:
        return None, {**info, "merge": "waiting"}
    if not folder.exists():
        return None, {**info, "merge": "merged"}
    try:
        return merge_study(study, out, wait_s=wait_s), {**info, "merge": "complete"}
    except FolderBusy:
        return None, {**info, "merge": "busy"}


def merge_study(study: Study, out: str | os.PathLike, *, wait_s: float = 0.0) -> list[dict]:
    """Move what the part folders finished into ``out`` and collect the study's rows (a ConfigError names a
    run with unfinished repeats)."""
    out = Path(out)
    with exclusive(out, what="study", kind="study"):
        rids, jobs = study_jobs(study)
        merge_parts(out, study_work(jobs), wait_s=wait_s)
        return collect(study, out, rids=rids)


def collect_variations(study: Study, out: str | os.PathLike) -> list[dict]:
    """The rows of the runs around the headline (:meth:`Study.variations`), each with ``variation`` (its
    kind), ``variation_key`` and ``variation_end``, aggregated over its own repeats."""
    variations = study.variations()
    rows = collect(study, out, runs=[v.params for v in variations], repeats=[v.repeats for v in variations])
    for row, v in zip(rows, variations):
        row.update({"variation": v.kind, "variation_key": v.key, "variation_end": v.end})
    return rows


def collect(study: Study, out: str | os.PathLike, *, rids: list[str] | None = None, runs: list[dict] | None = None,
            repeats: list[int] | None = None) -> list[dict]:
    """The result rows of a finished study (each run's repeats aggregated); each run's per-pixel maps
    are written to ``runs/<id>/maps.npz``. ``rids``: the runs' :func:`run_id` when known; ``runs`` and their
    ``repeats``: other runs than the sweep's (default: the sweep's, with the study's repeats)."""
    from gevsim.experiments.aggregate import aggregate_run
    from gevsim.experiments.repeat import finished_repeat, repeat_paths

    out = Path(out)
    rows = []
    runs = study.runs() if runs is None else runs
    counts = repeats or [study.base["repeats"]] * len(runs)
    for params, rid, n in zip(runs, rids or [run_id(study, p) for p in runs], counts):
        found = [finished_repeat(out, rid, r) for r in range(n)]
        records = [r for r in found if r is not None]
        if len(records) < len(found):
            raise ConfigError(f"run {rid} has unfinished repeats; run the study again to finish them",
                              source=str(out))
        arrays = []
        for r in range(n):
            with np.load(repeat_paths(out, rid, r)[1]) as data:
                arrays.append({k: data[k] for k in data.files})
        group = flicker_group(study, params.get("scene", study.base["scene"]))
        row, maps = aggregate_run(records, arrays, run_emulators(study, params), study.base["methods"], group)
        row["flicker_group"] = group
        with atomic_path(out / "runs" / rid / "maps.npz") as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **maps)
        rows.append(row)
    return rows


def check_study_scenes(study: Study) -> None:
    """Fail early (before any rendering) on a scene or flicker group that does not exist."""
    from gevsim.render import load

    for scene in study.axes.get("scene", [study.base["scene"]]):
        try:
            manifest = load(run_scene(study, {"scene": scene}))
        except ConfigError as exc:  # an unknown name has no file of its own: name the study's key (#19)
            if exc.source is not None:
                raise
            raise ConfigError(str(exc), source=study.source,
                              key="sweep.scene" if "scene" in study.axes else "study.scene") from None
        group = flicker_group(study, scene)
        if group not in manifest.group_names:
            raise ConfigError(f"scene {manifest.name!r} has no light group {group!r}"
                              f"{suggest(group, manifest.group_names)}", source=study.source,
                              key="study.flicker_group")
