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
from gevsim.experiments.study import Study, flicker_group, run_config, run_emulators, run_id, run_scene
from gevsim.io import atomic_path, exclusive, sweep_stale

__all__ = ["check_study_scenes", "collect", "collect_variations", "run_study"]


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
    :class:`~gevsim.errors.ConfigError` naming the folder (:func:`gevsim.io.exclusive`).
    """
    out = Path(out)
    with exclusive(out, what="study", kind="study"):  # one study at a time per folder: a second one is refused
        return _run_study(study, out, cache_dir=cache_dir, executor=executor, progress=progress,
                          keep_files=keep_files)


def _run_study(study: Study, out: Path, *, cache_dir, executor, progress, keep_files) -> list[dict]:
    from gevsim.experiments import repeat as rep

    (out / "runs").mkdir(parents=True, exist_ok=True)
    sweep_stale(out)  # what killed runs left half-written (stages nobody holds)
    runs = study.runs()
    rids = [run_id(study, p) for p in runs]  # once per run: it hashes every file of the scene
    jobs = [(p, rid, r) for p, rid in zip(runs, rids) for r in range(study.base["repeats"])]
    seen = {(rid, r) for _, rid, r in jobs}
    for v in study.variations():  # the runs around the headline (a trade-off setting may be a sweep run)
        rid = run_id(study, v.params)
        jobs += [(v.params, rid, r) for r in range(v.repeats) if (rid, r) not in seen]
        seen.update((rid, r) for r in range(v.repeats))
    todo = [(p, rid, r) for p, rid, r in jobs if rep.finished_repeat(out, rid, r) is None]
    total, done = len(jobs), len(jobs) - len(todo)
    kwargs: dict = {"keep_files": keep_files}
    if executor is not None:
        cache_dir = out / "render-cache" if cache_dir is None else cache_dir
        if todo:
            _prerender(study, [p for p, _, _ in todo], cache_dir)
        kwargs["threads"] = 1
    cache = None if cache_dir is None else str(cache_dir)
    calls = [((study, p, r, str(out)), {**kwargs, "rid": rid, "cache_dir": cache}) for p, rid, r in todo]
    run_all(rep.execute_repeat, calls, executor=executor, progress=progress, done=done, total=total)
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
