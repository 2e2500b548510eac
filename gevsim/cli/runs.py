"""``gevsim study`` and ``gevsim dataset``: many runs through an executor, resumable."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any, TypeVar

from gevsim.cli._common import _emulator_names, _progress, _quiet_dask, _render_overrides
from gevsim.errors import ConfigError

T = TypeVar("T")


def cmd_study(args: argparse.Namespace) -> int:
    import dataclasses

    from gevsim.experiments.report import write_study_outputs
    from gevsim.experiments.report_tables import comparison_table
    from gevsim.experiments.study import load_study
    from gevsim.experiments.study_run import check_study_scenes, run_study
    from gevsim.io import exclusive

    part = _part(args)
    study = load_study(args.config)
    base = dict(study.base)
    if args.repeats is not None:
        from gevsim.resources import MAX_REPEATS, at_most

        at_most(args.repeats, MAX_REPEATS, what="the number of repeats", source=None, key="--repeats")
        base["repeats"] = args.repeats
    if _render_overrides(args):
        base["render"] = {**base["render"], **_render_overrides(args)}
    if args.duration is not None:
        from gevsim._validate import FieldError
        from gevsim.timebase import TimeGrid

        base["duration_s"] = args.duration
        try:  # before the output folder and its runs/ are made
            TimeGrid(**{k: base[k] for k in ("duration_s", "step_s", "chunk_steps", "frame_rate_hz")})
        except FieldError as err:
            raise ConfigError(str(err), key="--duration") from None
    if (names := _emulator_names(args)) is not None:
        from gevsim.evaluation.methods import METHODS

        missing = sorted({METHODS[m].emulator for m in base["methods"]} - set(names))
        if missing:
            raise ConfigError(f"the study's methods need the emulators {', '.join(missing)}", key="--emulators")
        base["emulators"] = list(names)
    study = dataclasses.replace(study, base=base)
    check_study_scenes(study)
    _quiet_dask(args)
    if part is not None or args.merge:
        return _study_parts(args, study, part)
    with exclusive(args.out, what="study", kind="study"):  # a second study on this folder is refused before any work
        rows = _in_pool(args, f"study {study.name}", "job", lambda executor, update: run_study(
            study, args.out, cache_dir=args.cache, executor=executor, progress=update, keep_files=args.keep_files))
        report = write_study_outputs(args.out, study, rows)
    print(comparison_table(rows, study))
    print(f"gevsim: {len(rows)} runs x {study.base['repeats']} repeats; report {report}", file=sys.stderr)
    return 0


def cmd_dataset(args: argparse.Namespace) -> int:
    import dataclasses

    from gevsim.experiments.dataset import generate, load_dataset_config
    from gevsim.io import exclusive

    part = _part(args)
    config = load_dataset_config(args.config)
    changes: dict = {}
    if _render_overrides(args):
        changes["render"] = {**config.render, **_render_overrides(args)}
    if args.duration is not None:
        from gevsim._validate import FieldError

        try:
            changes["time"] = dataclasses.replace(config.time, duration_s=args.duration)
        except FieldError as err:  # as study and emulate do: one line naming the flag
            raise ConfigError(str(err), key="--duration") from None
    if (names := _emulator_names(args)) is not None:
        changes["emulators"] = names
    config = dataclasses.replace(config, **changes)
    _quiet_dask(args)
    if part is not None or args.merge:
        return _dataset_parts(args, config, part)
    with exclusive(args.out, what="dataset", kind="dataset"):
        summary = _in_pool(args, "dataset", "seq", lambda executor, update: generate(
            config, args.out, executor=executor, cache_dir=args.cache, progress=update))
    print(f"gevsim: {summary['sequences']} sequences: {summary['done']} made, {summary['skipped']} already done; "
          f"{summary['events']} events ({', '.join(f'{k} {v}' for k, v in summary['counts'].items())}); "
          f"wrote {args.out} in {summary['seconds']:.1f} s", file=sys.stderr)
    return 0


def _in_pool(args: argparse.Namespace, desc: str, unit: str, work: Callable[[Any, Any], T]) -> T:
    """``work(executor, progress)`` in the executor the flags name (``--executor``, ``--workers``,
    ``--scheduler``), with a progress bar closed however the work ends."""
    from gevsim.experiments.executors import make_executor

    with make_executor(args.executor, workers=args.workers, scheduler=args.scheduler) as executor:
        update, close = _progress(desc, not args.quiet, unit=unit)
        try:
            return work(executor, update)
        finally:
            close()


def _part(args: argparse.Namespace):
    """``--part I/N`` as a Part (None when not given); a bad one, or with ``--merge``, is one line."""
    from gevsim.experiments.parts import parse_part

    if args.part is None:
        return None
    if args.merge:
        raise ConfigError("--merge merges what the parts made and makes nothing: give --part or --merge, not both",
                          key="--part")
    return parse_part(args.part)


#: What a part says after its own line, by the state of the merge (``{out}``, ``{left}``, ``{again}``).
MERGE_LINES = {
    "waiting": "{left} not finished yet: the part that finishes last merges every part into {out}",
    "complete": "every part has finished: merged into {out}",
    "merged": "another part merged this one into {out}",
    "busy": "another gevsim run holds {out}: the merge of another part takes this one too; any other run leaves "
            "it to `{again} --merge` after it",
    "incomplete": "merged into {out}, but {left} not there yet (a part folder was busy): `{again} --merge` merges "
                  "it when that part has ended",
}


def _merge_line(args: argparse.Namespace, state: str, left: str) -> str:
    again = f"gevsim {args.command} {args.config} --out {args.out}"
    return "gevsim: " + MERGE_LINES[state].format(out=args.out, left=left, again=again)


def _dataset_parts(args: argparse.Namespace, config, part) -> int:
    """``gevsim dataset --part I/N`` (make a part; the last one merges) or ``--merge`` (only merge)."""
    from gevsim.experiments.dataset_parts import generate_part, merge

    if part is None:
        merged = merge(config, args.out)
        missing = f"; {merged['missing']} not finished anywhere (`gevsim dataset {args.config} --out {args.out}` " \
                  "makes them)" if merged["missing"] else " (complete)"
        busy = f"; {len(merged['busy'])} part folders busy, left for a later merge" if merged["busy"] else ""
        print(f"gevsim: merged {merged['moved']} sequences into {args.out}; dataset.json lists "
              f"{merged['sequences'] - merged['missing']} of {merged['sequences']}{missing}{busy}", file=sys.stderr)
        return 0
    summary = _in_pool(args, f"dataset part {part}", "seq", lambda executor, update: generate_part(
        config, args.out, part, executor=executor, cache_dir=args.cache, progress=update))
    print(f"gevsim: part {part}: {summary['sequences']} sequences: {summary['done']} made, {summary['skipped']} "
          f"already done; wrote {summary['out']} in {summary['seconds']:.1f} s", file=sys.stderr)
    left = summary["unfinished"]
    print(_merge_line(args, summary["merge"], f"{left} sequence{'s' * (left != 1)}"), file=sys.stderr)
    return 0


def _study_parts(args: argparse.Namespace, study, part) -> int:
    """``gevsim study --part I/N`` (run a part; the last one merges and reports) or ``--merge``."""
    from gevsim.experiments.report import write_study_outputs
    from gevsim.experiments.report_tables import comparison_table
    from gevsim.experiments.study_run import merge_study, run_study_part

    if part is None:
        rows = merge_study(study, args.out)  # a run with unfinished repeats is one line naming it
    else:
        found, info = _in_pool(args, f"study {study.name} part {part}", "job", lambda executor, update: run_study_part(
            study, args.out, part, cache_dir=args.cache, executor=executor, progress=update,
            keep_files=args.keep_files))
        print(f"gevsim: part {part}: {info['jobs']} jobs: {info['made']} made, {info['jobs'] - info['made']} "
              f"already done; wrote {info['out']}", file=sys.stderr)
        left = info["unfinished"]
        print(_merge_line(args, info["merge"], f"{left} job{'s' * (left != 1)}"), file=sys.stderr)
        if found is None:
            return 0
        rows = found
    report = write_study_outputs(args.out, study, rows)
    print(comparison_table(rows, study))
    print(f"gevsim: {len(rows)} runs x {study.base['repeats']} repeats; report {report}", file=sys.stderr)
    return 0
