"""Helpers the commands share: argparse types, progress bars, run overrides."""

from __future__ import annotations

import argparse
import logging
import math
import sys
from collections.abc import Callable

from gevsim.errors import ConfigError


def _positive(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = float(text)
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value


def _non_negative(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = float(text)
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative number, got {text}")
    return value


def _int_at_least(low: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``low``."""
    wanted = {0: "a non-negative integer", 1: "a positive integer"}.get(low, f"an integer >= {low}")

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}")
        return value

    return parse


_positive_int = _int_at_least(1)


_non_negative_int = _int_at_least(0)


def _progress(desc: str, enabled: bool, unit: str = "pose"):
    """A ``progress(done, total)`` callback drawing a tqdm bar (nothing with ``-q``). Where stderr is not a
    terminal (a log file, ``make demo`` piped), where a bar's redraws would fill the file, one line at each
    tenth of the work and at least every :data:`LOG_EVERY_S` seconds instead: long work is never silent."""
    if not enabled:
        return None, lambda: None
    if not sys.stderr.isatty():
        return _log_lines(desc, unit), lambda: None
    from tqdm import tqdm

    bar = tqdm(desc=desc, unit=unit, leave=True, dynamic_ncols=True)

    def update(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    return update, bar.close


#: Without a terminal, a progress line at least this often (s) while work finishes.
LOG_EVERY_S = 30.0


def _log_lines(desc: str, unit: str):
    """``progress(done, total)`` writing "desc: 12/76 jobs (15 %), 41 s" lines to stderr."""
    import time

    start = time.monotonic()
    last = {"tenth": -1, "at": start}

    def update(done: int, total: int) -> None:
        now = time.monotonic()
        tenth = 10 * done // max(total, 1)
        if tenth > last["tenth"] or now - last["at"] >= LOG_EVERY_S or done == total:
            last.update(tenth=tenth, at=now)
            print(f"{desc}: {done}/{total} {unit}s ({100 * done // max(total, 1)} %), {now - start:.0f} s",
                  file=sys.stderr, flush=True)

    return update


def _emulator_names(args: argparse.Namespace, choices=None) -> tuple[str, ...] | None:
    """``--emulators a,b`` as registry names (None when not given); unknown names are a ConfigError."""
    from gevsim.emulation.emulators import EMULATORS, check_emulator_list

    if args.emulators is None:
        return None
    try:
        return check_emulator_list([n.strip() for n in args.emulators.split(",") if n.strip()],
                                   tuple(choices or EMULATORS))
    except ValueError as exc:
        raise ConfigError(str(exc), key="--emulators") from None


def _render_overrides(args: argparse.Namespace) -> dict:
    return {k: v for k, v in (("width", args.width), ("height", args.height)) if v is not None}


def _quiet_dask(args: argparse.Namespace) -> None:
    """distributed sets its loggers to INFO on import: back to WARNING unless --verbose."""
    if args.executor != "dask" or args.verbose:
        return
    try:
        import distributed  # noqa: F401
    except ImportError:
        return  # make_executor says what to install
    for name in [n for n in logging.root.manager.loggerDict if n.split(".")[0] == "distributed"]:
        logging.getLogger(name).setLevel(logging.WARNING)


def _run_overrides(parser: argparse.ArgumentParser) -> None:
    """--width/--height/--duration/--emulators: override the config's values for this run."""
    parser.add_argument("--width", type=_positive_int, help="render width in pixels (overrides the config)")
    parser.add_argument("--height", type=_positive_int, help="render height in pixels (overrides the config)")
    parser.add_argument("--duration", type=_positive, metavar="S", help="duration in seconds (overrides the config)")
    parser.add_argument("--emulators", metavar="LIST", help="comma-separated emulators (overrides the config), "
                                                            "e.g. dvs,gradient")


def _executor_options(parser: argparse.ArgumentParser) -> None:
    from gevsim.experiments.executors import EXECUTORS

    parser.add_argument("--executor", choices=tuple(EXECUTORS), default="local",
                        help="local process pool (default) or Dask distributed")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address (default: a LocalCluster)")
    parser.add_argument("--workers", type=_positive_int, metavar="N",
                        help="worker processes (default: the number of CPUs)")
