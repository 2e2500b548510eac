"""AEDAT4 export (the file format of iniVation's DV tools, which v2e also writes) through
iniVation's maintained ``dv-processing`` library (extra ``aedat4``).

AEDAT4 event streams carry polarity events (timestamp in microseconds, x, y, a boolean
polarity). gevsim's streams map onto them as:

- the brightness stream ``events`` (DVS): the AEDAT4 event stream ``events``, polarity = ON;
- every other stream ``<kind>_events`` is named ``events_<kind>`` (center-surround:
  ``events_csdvs``), and a gradient stream (ternary gradient codes, one event per change of
  a pixel's x or y code by one step) becomes two, ``events_<kind>_x`` and ``events_<kind>_y``,
  with polarity = the step is upward (``p = +1``).

dv-processing numbers a file's streams in alphabetical order of their names, whatever order
they are added in, and readers that take "the" event stream take the first (tonic's
``read_aedat4``, ``getNextEventBatch()`` without a name): so the DVS stream's name sorts first
(issue 26: ``csdvs_events`` used to, and was read as the DVS).

Timestamps stay in microseconds from the start of the emulation. The output file is written
next to its final name and renamed into place when complete.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from gevsim._resources import ensure_room
from gevsim.errors import ConfigError, MissingExtraError
from gevsim.io._child import run_in_child
from gevsim.io._h5discard import sink_path
from gevsim.io.atomic import atomic_path
from gevsim.io.hdf5 import EventReader
from gevsim.io.ownership import check_file, sweep_beside
from gevsim.resources import AEDAT4_EVENT_BYTES, check_export  # dv-processing aborts on a full disk

__all__ = ["aedat4_name", "aedat4_streams", "export_aedat4", "read_aedat4"]

WINDOW_US = 50_000  # events are read and written 50 ms at a time
MAGIC = b"#!AER-DAT4.0"  # how every AEDAT4 file starts
CAMERA = "gevsim"  # the camera name of gevsim's exports


def _dv():
    try:
        import dv_processing as dv
    except ImportError:
        raise MissingExtraError("AEDAT4 export needs dv-processing: pip install 'gevsim[aedat4]'") from None
    return dv


def aedat4_name(stream: str) -> str:
    """The AEDAT4 name of a gevsim stream: ``events`` stays, ``<kind>_events`` becomes ``events_<kind>``
    (so the DVS stream sorts first; see the module notes)."""
    if stream == "events":
        return stream
    return "events_" + (stream[:-len("_events")] if stream.endswith("_events") else stream)


def aedat4_streams(reader: EventReader) -> dict[str, tuple[str, int | None]]:
    """AEDAT4 stream name -> (gevsim stream, gradient axis or None) for the streams of a file."""
    out: dict[str, tuple[str, int | None]] = {}
    for stream in reader.streams:
        name = aedat4_name(stream)
        if "axis" in (reader.dtype(stream).names or ()):
            out[f"{name}_x"] = (stream, 0)
            out[f"{name}_y"] = (stream, 1)
        else:
            out[name] = (stream, None)
    return dict(sorted(out.items()))


def _store(dv, events: np.ndarray):
    store = dv.EventStore()
    push = store.push_back
    for t, x, y, p in zip(events["t"].tolist(), events["x"].tolist(), events["y"].tolist(),
                          (events["p"] > 0).tolist()):
        push(t, x, y, p)
    return store


def _busy_windows(reader: EventReader, streams) -> list[int]:
    """Starts of the WINDOW_US windows covering [0, t_end_us] that may hold events of ``streams`` (judged
    from ms_to_idx): a long recording's empty stretches are skipped, not read window by window."""
    starts = np.arange(0, reader.t_end_us + 1, WINDOW_US, dtype=np.int64)
    busy = np.zeros(len(starts), bool)
    for stream in streams:
        busy |= reader.index_bounds(stream, starts + WINDOW_US)[1] > reader.index_bounds(stream, starts)[0]
    return starts[busy].tolist()


def _is_gevsim_aedat4(path: Path) -> bool:
    """Whether ``path`` is an AEDAT4 file gevsim exported: the magic, then a header whose streams' source
    (the camera name) is ``gevsim`` (read as bytes: no parser runs on a file that may not be ours)."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    return head.startswith(MAGIC) and f'<attr key="source" type="string">{CAMERA}</attr>'.encode() in head


def export_aedat4(path: str | os.PathLike, out: str | os.PathLike, *, streams: list[str] | None = None) -> dict:
    """Write the event streams of an emulation file ``path`` as an AEDAT4 file ``out``.

    ``streams`` names gevsim streams to export (default: all). Returns the AEDAT4 stream
    names with their event counts.
    """
    _dv()  # a missing extra is said before any work
    out = Path(out)
    check_file(out, "AEDAT4", _is_gevsim_aedat4, inputs=[path])  # replaces only an earlier export, never the input
    sweep_beside(out)
    with EventReader(path) as r:
        mapping = aedat4_streams(r)
        if streams is not None:
            unknown = sorted(set(streams) - set(r.streams))
            if set(unknown) & r.left_out.keys():  # not a stream's columns: never exported unchecked
                s = min(set(unknown) & r.left_out.keys())
                raise ConfigError(f"stream {s!r} is left out: {r.left_out[s]}", source=str(path), key="stream")
            if unknown:
                raise ConfigError(f"no stream {', '.join(map(repr, unknown))} in the file; it has "
                                  f"{', '.join(r.streams) or 'none'}", source=str(path), key="stream")
            mapping = {k: v for k, v in mapping.items() if v[0] in streams}
        if not mapping:
            raise ConfigError("the file holds no event stream to export", source=str(path))
        size = (r.width, r.height)
        check_export(sum(r.count(s) for s in dict.fromkeys(s for s, _ in mapping.values())), out, source=str(out))
    with atomic_path(out, suffix=".aedat4") as tmp:  # dv-processing aborts its process on a failed write
        return run_in_child(_write, path, tmp, out, mapping, size, target=out)


def _write(path: str | os.PathLike, tmp: Path, out: Path, mapping: dict, size: tuple[int, int]) -> dict:
    """Write the streams ``mapping`` of ``path`` into ``tmp`` (the stage of ``out``); their event counts."""
    dv = _dv()
    config = dv.io.MonoCameraWriter.Config(CAMERA)
    for name in mapping:
        config.addEventStream(size, name)
    counts = dict.fromkeys(mapping, 0)
    streams = dict.fromkeys(s for s, _ in mapping.values())
    with EventReader(path) as r:
        writer = dv.io.MonoCameraWriter(str(tmp), config)
        failed = True
        try:
            for start in _busy_windows(r, streams):
                for stream in streams:
                    ev = r.read(stream, start, start + WINDOW_US)
                    for name, (s, axis) in mapping.items():
                        if s != stream:
                            continue
                        sel = ev if axis is None else ev[ev["axis"] == axis]
                        if len(sel):  # room first: a write that fails in dv-processing aborts the process
                            ensure_room(out, len(sel) * AEDAT4_EVENT_BYTES)
                            writer.writeEvents(_store(dv, sel), name)
                            counts[name] += len(sel)
            failed = False
        finally:
            if failed:  # the file is thrown away: its last writes go nowhere (a full disk would abort dv)
                sink_path(tmp)
            del writer  # closes the file: its last packets and index are written here
    return counts


def read_aedat4(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """All events of every event stream of an AEDAT4 file: name -> structured array (timestamp, x, y,
    polarity), for round trips and tests."""
    dv = _dv()
    recording = dv.io.MonoCameraRecording(str(path))
    out = {}
    for name in recording.getStreamNames():
        if not recording.isStreamOfEventType(name):
            continue
        parts = []
        while (batch := recording.getNextEventBatch(name)) is not None:
            parts.append(batch.numpy())
        out[name] = np.concatenate(parts) if parts else np.zeros(0, dv.EventStore().numpy().dtype)
    return out
