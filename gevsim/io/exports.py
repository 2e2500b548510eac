"""``gevsim export``: an emulation file's events in the formats other tools read, a registry of writers.

- ``aedat4``: iniVation's AEDAT4 (:mod:`gevsim.io.aedat4`; DV tools, tonic's ``read_aedat4``).
- ``text``: one stream, ``t x y p`` a line with t in **seconds** (the community text format of
  ESIM/rpg_dvs_ros, E2VID and EVREAL's tooling; gradient streams add an ``axis`` column); the first
  line is a ``#`` comment, so ``numpy.loadtxt`` and readers that skip one header line both read it.
  With ``header="e2vid"`` (``--header e2vid``) the first line is the sensor size ``W H``, where E2VID's
  ``run_reconstruction.py`` reads it (brightness streams only); that file carries no gevsim mark, so it
  is never replaced by a later export.
- ``npz``: every stream (or the chosen ones) as a NumPy structured array under its stream name, with
  tonic's fields (``x``, ``y`` int16, ``t`` int64 us, ``p``), and ``width`` and ``height``.
- ``evreal``: the DVS stream and tone-mapped ground-truth frames as an EVREAL sequence folder
  (:func:`gevsim.io.evreal.export_evreal`).

Each replaces only an earlier gevsim export of its kind, never an input (:mod:`gevsim.io.ownership`),
and is written next to its name, then renamed into place.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gevsim.errors import ConfigError, suggest
from gevsim.io.atomic import atomic_path
from gevsim.io.hdf5 import EventReader
from gevsim.io.ownership import check_file, check_inputs_outside, sweep_beside

__all__ = ["FORMATS", "HEADERS", "export"]

#: First lines of the text export: gevsim's ``#`` comment, or E2VID's sensor size ``W H``.
HEADERS = ("gevsim", "e2vid")


def _streams(reader: EventReader, streams: list[str] | None) -> list[str]:
    if streams is None:
        return list(reader.streams)
    for s in streams:
        if s in reader.left_out:  # its columns are not a stream's: never exported unchecked (issue 36, item 3)
            raise ConfigError(f"stream {s!r} is left out: {reader.left_out[s]}", source=str(reader.path),
                              key="--stream")
        if s not in reader.streams:
            raise ConfigError(f"no stream {s!r} in the file{suggest(s, reader.streams)}; it has "
                              f"{', '.join(reader.streams) or 'none'}", source=str(reader.path), key="--stream")
    return list(streams)


def _is_gevsim_text(path: Path) -> bool:
    with open(path, "rb") as fh:
        first = fh.readline(4096)
    return first.startswith(b"# t x y p") and b"(gevsim " in first


def _is_gevsim_npz(path: Path) -> bool:
    try:
        with zipfile.ZipFile(path) as z:
            return "gevsim_version.npy" in z.namelist()
    except (zipfile.BadZipFile, OSError):
        return False


def export_text_file(path: str | os.PathLike, out: Path, streams: list[str] | None, *,
                     header: str = "gevsim") -> dict:
    """One stream (``events`` unless named) as ``t x y p`` lines, t in seconds, after a ``header`` line
    (:data:`HEADERS`)."""
    from gevsim.io.text import export_text

    with EventReader(path) as r:
        chosen = _streams(r, streams) if streams is not None else ["events"] if "events" in r.streams else []
        if len(chosen) != 1:
            raise ConfigError(f"the text format holds one stream; name it with --stream (streams: "
                              f"{', '.join(r.streams)})", source=str(path), key="--stream")
        if header == "e2vid" and "axis" in (r.dtype(chosen[0]).names or ()):
            raise ConfigError(f"E2VID reads brightness events (t x y p); {chosen[0]!r} is a gradient stream",
                              source=str(path), key="--header")
        events, size = r.read(chosen[0]), (r.width, r.height)
    check_file(out, "text export", _is_gevsim_text, inputs=[path])
    export_text(out, events, seconds=True, e2vid_size=size if header == "e2vid" else None)
    return {chosen[0]: len(events)}


def export_npz(path: str | os.PathLike, out: Path, streams: list[str] | None) -> dict:
    """Every stream (or the chosen ones) as structured arrays in one ``.npz``."""
    from gevsim import __version__

    with EventReader(path) as r:
        arrays = {s: r.read(s) for s in _streams(r, streams)}
        size = {"width": np.int64(r.width), "height": np.int64(r.height)}
    check_file(out, "npz export", _is_gevsim_npz, inputs=[path])
    with atomic_path(out) as tmp, open(tmp, "wb") as fh:
        payload: dict[str, Any] = {**arrays, **size, "gevsim_version": np.str_(__version__)}
        np.savez_compressed(fh, **payload)
    return {k: len(v) for k, v in arrays.items()}


def export_evreal_folder(path: str | os.PathLike, out: Path, streams: list[str] | None) -> dict:
    """The DVS stream and the ground truth as an EVREAL sequence folder."""
    from gevsim.io.evreal import export_evreal_from

    if streams not in (None, ["events"]):
        raise ConfigError("EVREAL sequences hold the DVS stream ('events') only", source=str(path), key="--stream")
    check_inputs_outside(out, [path])
    if os.path.lexists(out) and not (out.is_dir() and _is_gevsim_evreal(out)):
        raise ConfigError("exists and is not a gevsim EVREAL folder; choose another output", source=str(out))
    return export_evreal_from(path, out)


def _is_gevsim_evreal(folder: Path) -> bool:
    """An EVREAL folder gevsim wrote: its metadata.json names gevsim, and it holds nothing else but the
    EVREAL files."""
    try:
        meta = (folder / "metadata.json").read_text()
    except OSError:
        return False
    return '"gevsim' in meta and all(p.suffix in (".npy", ".json") for p in folder.iterdir())


def export_aedat4_file(path: str | os.PathLike, out: Path, streams: list[str] | None) -> dict:
    from gevsim.io.aedat4 import export_aedat4

    return export_aedat4(path, out, streams=streams)


#: format name -> writer(emulation file, output, streams or None) -> {stream: events written}.
FORMATS: dict[str, Callable[[str | os.PathLike, Path, list[str] | None], dict]] = {
    "aedat4": export_aedat4_file,
    "text": export_text_file,
    "npz": export_npz,
    "evreal": export_evreal_folder,
}


def export(path: str | os.PathLike, out: str | os.PathLike, fmt: str, *, streams: list[str] | None = None,
           header: str | None = None) -> dict:
    """Write the events of emulation file ``path`` to ``out`` in format ``fmt`` (:data:`FORMATS`); ``header``:
    the text format's first line (:data:`HEADERS`, default ``"gevsim"``)."""
    if fmt not in FORMATS:
        raise ConfigError(f"unknown export format {fmt!r}{suggest(fmt, FORMATS)}; one of {', '.join(FORMATS)}",
                          key="--format")
    if header is not None and (fmt != "text" or header not in HEADERS):
        raise ConfigError(f"the text format's header is one of {', '.join(HEADERS)}, got {header!r}"
                          if fmt == "text" else f"applies to --format text only, not {fmt}", key="--header")
    out = Path(out)
    sweep_beside(out)
    if fmt == "text":
        return export_text_file(path, out, streams, header=header or "gevsim")
    return FORMATS[fmt](path, out, streams)
