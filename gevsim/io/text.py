"""Plain-text events: one ``t x y p`` line per event (t in integer microseconds, or in seconds).

Brightness events are written as ``t x y p`` with p = 1 (ON) or 0 (OFF);
gradient events as ``t x y p axis`` with p = +1/-1 and axis 0 (X) or 1 (Y).
The first line is a ``#`` comment naming the columns; or, for E2VID (Rebecq et al., TPAMI 2019;
github.com/uzh-rpg/rpg_e2vid, whose ``run_reconstruction.py`` reads the sensor size from the first line
of the file and whose ``utils/event_readers.py`` skips that line and reads ``t x y p`` lines, t in
seconds, p 0 or 1), the sensor size ``W H`` (``e2vid_size``). Such a file carries no gevsim mark, so
``gevsim export`` never replaces one (:mod:`gevsim.io.exports`).
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import numpy as np

from gevsim import __version__
from gevsim.errors import ConfigError
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE, check_events, is_gradient
from gevsim.io.atomic import atomic_path

_ROWS = 2**16  # lines formatted per write
_E2VID_HEADER = re.compile(r"[1-9][0-9]* [1-9][0-9]*")  # the first line of E2VID's layout: "W H"


def export_text(path: str | os.PathLike, events: np.ndarray, *, seconds: bool = False,
                e2vid_size: tuple[int, int] | None = None) -> Path:
    """Write ``events`` (brightness or gradient) to a text file, atomically; ``seconds``: t in seconds
    with 6 decimals (exact: whole microseconds), the community format, instead of integer microseconds.
    ``e2vid_size`` ``(width, height)``: E2VID's layout, whose first line is ``W H`` (brightness events,
    t in seconds; see the module's notes)."""
    check_events(events)
    gradient = is_gradient(events)
    names = ("t", "x", "y", "p", "axis") if gradient else ("t", "x", "y", "p")
    polarity = "p: +1/-1" if gradient else "p: 1 = ON, 0 = OFF"
    unit = "seconds" if seconds else "microseconds"
    header = f"# {' '.join(names)}  (gevsim {__version__}; t in {unit}; {polarity}; axis: 0 = X, 1 = Y)\n"
    if not gradient:
        header = header.replace("; axis: 0 = X, 1 = Y", "")
    if e2vid_size is not None:
        width, height = e2vid_size
        if gradient or not seconds:
            raise ValueError("E2VID's text layout holds brightness events (t x y p) with t in seconds")
        if not all(isinstance(v, int | np.integer) and v >= 1 for v in (width, height)):
            raise ValueError(f"e2vid_size must be two positive integers (width, height), got {e2vid_size!r}")
        header = f"{int(width)} {int(height)}\n"
    line = " ".join(["%.6f" if seconds else "%d"] + ["%d"] * (len(names) - 1)) + "\n"
    with atomic_path(path) as tmp, open(tmp, "w") as f:
        f.write(header)
        for start in range(0, len(events), _ROWS):
            chunk = events[start:start + _ROWS]
            cols = [chunk[name].astype(np.int64) for name in names]
            if seconds:  # an int64 microsecond count divided by 1e6: %.6f prints it back exactly
                rows = zip((chunk["t"] / 1e6).tolist(), *(c.tolist() for c in cols[1:]))
                f.write("".join(line % r for r in rows))
            else:
                table = np.stack(cols, axis=1)
                f.write((line * len(chunk)) % tuple(table.ravel().tolist()))
    return Path(path)


def import_text(path: str | os.PathLike) -> np.ndarray:
    """Read a file written by :func:`export_text` (4 or 5 columns; E2VID's layout too, its ``W H`` line skipped)."""
    path = Path(path)
    src = str(path)
    if not path.is_file():
        raise ConfigError("no such file", source=src)
    with open(path) as f:
        first = f.readline()
    e2vid = _E2VID_HEADER.fullmatch(first.rstrip("\n")) is not None  # "W H": E2VID's layout, t in seconds
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            if "t in seconds" in first or e2vid:  # microseconds printed with 6 decimals: back to whole microseconds
                table = np.loadtxt(path, dtype=np.float64, comments="#", ndmin=2, skiprows=1 if e2vid else 0)
                table[:, 0] *= 1e6
                table = np.rint(table).astype(np.int64)
            else:
                table = np.loadtxt(path, dtype=np.int64, comments="#", ndmin=2)
    except ValueError as exc:
        raise ConfigError(f"not a 't x y p [axis]' integer table ({exc})", source=src) from None
    if table.shape[0] == 0:  # no events: the header says which kind (E2VID's: brightness)
        header = [] if e2vid else first.lstrip("#").split("(")[0].split()
        table = np.zeros((0, 5 if "axis" in header else 4), dtype=np.int64)
    if table.shape[1] not in (4, 5):
        raise ConfigError(f"expected 4 (t x y p) or 5 (t x y p axis) columns, got {table.shape[1]}", source=src)
    gradient = table.shape[1] == 5
    t, x, y, p = table[:, 0], table[:, 1], table[:, 2], table[:, 3]
    allowed = (-1, 1) if gradient else (0, 1)
    checks = [
        (np.isin(p, allowed), f"polarity must be one of {allowed}"),
        ((x >= -(2**15)) & (x < 2**15) & (y >= -(2**15)) & (y < 2**15), "x and y must fit int16"),
        (np.isin(table[:, 4], (0, 1)) if gradient else np.ones(len(t), bool), "axis must be 0 or 1"),
        (np.r_[True, np.diff(t) >= 0], "timestamps must be non-decreasing"),
    ]
    for ok, message in checks:
        if not ok.all():
            row = int(np.argmin(ok))
            raise ConfigError(f"{message}; bad event #{row}: {table[row].tolist()}", source=src)
    events = np.empty(len(t), dtype=GRADIENT_DTYPE if gradient else BRIGHTNESS_DTYPE)
    events["t"], events["x"], events["y"] = t, x, y
    events["p"] = p if gradient else p.astype(bool)
    if gradient:
        events["axis"] = table[:, 4]
    return events
