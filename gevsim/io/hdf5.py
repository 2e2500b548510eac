"""DSEC-compatible HDF5 event files (DESIGN.md, Data contracts).

Layout (format ``"gevsim-events-2"``)::

    /                      attrs: width, height, config_toml, seed, gevsim_version,
                                  format, complete, t_end_us, extra attributes
    /events/{x,y,t,p}      brightness events, one 1-D dataset per field; p uint8, 1 = ON, 0 = OFF
    /events/ms_to_idx      ms_to_idx[k] = index of the first event with t >= k*1000 us
    /ms_to_idx             the same dataset (a hard link), where DSEC's tools look for it
    /t_offset              int64 us added to events/t for absolute time (0)
    /gradient_events/{x,y,t,p,axis}, /gradient_events/ms_to_idx
    /<stream>/...          any other named stream, same layout (read back when its columns are those of a
                           brightness or gradient stream; any other is left out, gevsim.io.checks.left_out)
    /frames/<name>/images  (N, H, W[, C]) and /frames/<name>/t (N,) int64 us

The brightness stream is laid out as DSEC's ``events.h5`` (Gehrig et al., RA-L 2021;
github.com/uzh-rpg/DSEC, ``scripts/utils/eventslicer.py`` reads ``events/{p,x,y,t}``,
the root ``ms_to_idx`` and ``t_offset``), so DSEC's slicer and loaders read it as is.
Every stream has its own ``ms_to_idx`` with ``ceil(t_end_us / 1000) + 1`` entries.
Boolean fields (the brightness polarity) are stored as uint8 0/1, not as an HDF5 enum,
and read back as bool. Every dataset carries ``units`` and ``meaning`` attributes.
Timestamps must be non-negative. Every dataset is stored in the file itself (no external storage,
external link or virtual dataset; the reader refuses them, :mod:`gevsim.io.sealed`). Files of format
``"gevsim-events-1"`` (bool enum polarity, no root ``ms_to_idx``) are still read. The file is written
under a temporary name beside the target and renamed onto it only by a clean :meth:`EventWriter.close`,
so a file at the target path always carries ``complete = True``.

Storage. The event columns keep their in-memory dtypes, which are already the smallest exact ones for
the sensors gevsim models (x, y int16; t int64; p, axis one byte each). They are stored in chunks of
:data:`CHUNK` events, byte-shuffled (HDF5's built-in ``shuffle`` filter) and deflated (``gzip``, level
:data:`GZIP_LEVEL` by default) or ``lzf``: filters that h5py reads without plugins. DSEC stores t in
fewer bits relative to ``t_offset`` (DSEC's README; the same group's writer in uzh-rpg/dagr,
``scripts/downsample_events.py``, writes x, y, p, t as ``u2, u2, u1, u4`` with Blosc, a plugin); after
the shuffle the constant high bytes of an int64 t compress to almost nothing (uint32 would save under
0.02 byte per event, ``benchmarks/storage.py``) and int64 never wraps (uint32 microseconds wrap after
71.6 min), so the layout, and the format name, stay as they were: older readers read the new files.
Bytes per event on flicker and gradient-chatter streams are in ``benchmarks/README.md`` (about 1.9 and
2.2, from 13 and 14 in memory).

Event chunks are compressed and written by one background thread (``background=True``, the default):
:meth:`EventWriter.append` validates in the caller's thread, copies the chunk and queues it (at most
:data:`QUEUE_CHUNKS` waiting; the caller blocks beyond), so compression overlaps emulation (h5py
releases the GIL while HDF5 compresses and writes, h5py 3.0 release notes). A failure in the thread is
raised again, with its message, by the next ``append``, ``wait`` or ``close`` (and every later one);
``close`` and leaving a ``with`` block then discard the file. The columns are gathered into whole chunks
before they are written, so the datasets, and the events read back, do not depend on how the stream was
split into appends nor on the thread. Every other change to the file (a new stream's group, a frame, an
array, an attribute) waits first for the chunks queued before it, so HDF5 allocates the file's space in one
order whatever the thread's timing: the same run writes the same bytes (issue 37, item 6).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np

from gevsim import __version__
from gevsim.io._h5discard import close_h5, discard_h5, ensure_room
from gevsim.io._hdf5_stream import (  # noqa: F401 (re-exported: gevsim.io.hdf5.CHUNK, ...)
    CHUNK,
    FIELD_ATTRS,
    FRAME_T_ATTRS,
    MS_TO_IDX_ATTRS,
    T_OFFSET_ATTRS,
    _describe,
    _filters,
    _settle,
    _Stream,
)
from gevsim.io._worker import _Worker
from gevsim.io.atomic import Staged
from gevsim.io.checks import BOOL_ATTR  # noqa: F401 (re-exported)
from gevsim.io.checks import STANDARD as _STANDARD
from gevsim.io.event_reader import FORMAT, READABLE_FORMATS, EventReader  # noqa: F401 (re-exported)

log = logging.getLogger(__name__)

#: Default deflate level of ``compression="gzip"``: level 1 after the shuffle filter is 4-6 % smaller than
#: the former default (level 4, no shuffle) on DVS streams, 1 % larger on gradient chatter, and 1.7-1.9x
#: faster to write (benchmarks/README.md, "Event storage").
GZIP_LEVEL = 1
#: Event chunks queued for the writer thread beyond the one it is writing (the caller blocks when full).
QUEUE_CHUNKS = 2
_RESERVED_ATTRS = {"width", "height", "config_toml", "seed", "gevsim_version", "format", "complete", "t_end_us"}

class EventWriter:
    """Append event streams, frames and arrays to a gevsim HDF5 file.

    Parameters
    ----------
    path : str or PathLike
        Target file; it appears only after a clean :meth:`close`.
    width, height : int
        Sensor size in pixels.
    config_toml : str
        The resolved configuration as TOML text.
    seed : int
        Seed of the run.
    compression : {"gzip", "lzf"}
        Filter for every dataset (both ship with h5py; no plugin needed to read), after HDF5's
        shuffle filter for items of several bytes.
    gzip_level : int
        Deflate level (1-9) with ``compression="gzip"``.
    background : bool
        Compress and write the event streams in a background thread (see the module's notes); the
        file's content is the same either way.
    extra_attrs : dict, optional
        More root attributes.
    """

    def __init__(self, path: str | os.PathLike, *, width: int, height: int, config_toml: str, seed: int,
                 compression: str = "gzip", gzip_level: int = GZIP_LEVEL, background: bool = True,
                 extra_attrs: dict | None = None):
        if compression not in ("gzip", "lzf"):
            raise ValueError(f"compression must be 'gzip' or 'lzf', got {compression!r}")
        if isinstance(gzip_level, bool) or not isinstance(gzip_level, int | np.integer) or not 1 <= gzip_level <= 9:
            raise ValueError(f"gzip_level must be an integer from 1 to 9, got {gzip_level!r}")
        self.path = Path(path)
        self.compression = compression
        self._filters = {"compression": compression, "compression_opts": int(gzip_level) if compression == "gzip"
                         else None}
        self._worker: _Worker | None = None
        self._background = bool(background)
        self._stage = Staged(self.path, suffix=".tmp")
        self._tmp = self._stage.path
        self._streams: dict[str, _Stream] = {}
        self._t_end_us: int | None = None
        try:
            # The stage holds its own lock (gevsim.io.atomic); HDF5's would conflict with it.
            self._file = h5py.File(self._tmp, "w", locking=False)
            attrs = self._file.attrs
            attrs.update(width=int(width), height=int(height), config_toml=str(config_toml), seed=int(seed),
                         gevsim_version=__version__, format=FORMAT)
            for key in extra_attrs or {}:
                if key in _RESERVED_ATTRS:
                    raise ValueError(f"extra_attrs key {key!r} is reserved")
            self.set_attrs("/", **(extra_attrs or {}))
        except BaseException:
            self.abort()
            raise

    # -- context manager -------------------------------------------------------------
    def __enter__(self) -> EventWriter:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    @property
    def closed(self) -> bool:
        return self._file is None or not self._file.id.valid

    def _check_open(self) -> None:
        if self.closed:
            raise ValueError(f"{self.path}: writer is closed")
        if self._worker is not None:
            self._worker.check()  # a failure of the writer thread, raised again here

    def _write(self, state: _Stream, events: np.ndarray, ms: np.ndarray) -> None:
        """Hand validated events to the writer thread (a copy: the caller may reuse its array), or
        write them here without one."""
        ensure_room(self.path, events.nbytes)  # before HDF5 sees it: a full disk inside HDF5 can crash h5py
        if self._background and self._worker is None:
            self._worker = _Worker(QUEUE_CHUNKS)
        if self._worker is not None:
            events = events.copy()
            self._worker.submit(lambda: state.write(events, ms))
        else:
            state.write(events, ms)

    # -- events ------------------------------------------------------------------------
    def append(self, stream: str, events: np.ndarray) -> None:
        """Append a chunk of time-sorted events to ``stream`` (e.g. ``"events"``)."""
        self._check_open()
        if not isinstance(events, np.ndarray) or events.dtype.names is None or "t" not in events.dtype.names:
            got = getattr(events, "dtype", type(events).__name__)
            raise TypeError(f"stream {stream!r}: events must be a structured array with a 't' field, got {got}")
        state = self._streams.get(stream) or self._create_stream(stream, events.dtype)
        if events.dtype != state.dtype:
            raise TypeError(f"stream {stream!r}: chunk dtype {events.dtype} differs from the stream's {state.dtype}")
        events = events.reshape(-1)
        t = np.asarray(events["t"], dtype=np.int64)
        if len(t) == 0:
            return
        if t[0] < 0:
            raise ValueError(f"stream {stream!r}: timestamps must be >= 0 us, got t={int(t[0])} us")
        if state.last_t is not None and t[0] < state.last_t:
            raise ValueError(f"stream {stream!r}: timestamps go back across appends: chunk starts at "
                             f"t={int(t[0])} us but the previous chunk ended at t={state.last_t} us")
        bad = np.flatnonzero(np.diff(t) < 0)
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"stream {stream!r}: timestamps must be non-decreasing, "
                             f"got t[{i}]={int(t[i])} us then t[{i + 1}]={int(t[i + 1])} us")
        n0 = state.n
        k_last = int(t[-1]) // 1000  # entries k <= k_last are now final
        ks = np.arange(state.n_ms, k_last + 1, dtype=np.int64) * 1000
        ms = n0 + np.searchsorted(t, ks, side="left")
        self._write(state, events, ms)
        state.n, state.last_t, state.n_ms = n0 + len(t), int(t[-1]), state.n_ms + len(ms)

    def _in_order(self) -> None:
        """Wait for the queued chunks before any other change to the file: the file's layout (HDF5 allocates
        space in the order of the writes) then does not depend on the writer thread's timing."""
        if self._worker is not None:
            self._worker.wait()

    def _create_stream(self, stream: str, dtype: np.dtype) -> _Stream:
        if not isinstance(stream, str) or not stream or "/" in stream or stream == "frames":
            raise ValueError(f"invalid stream name {stream!r}: a non-empty name without '/', not 'frames'")
        if stream in _STANDARD and dtype != _STANDARD[stream]:
            raise TypeError(f"stream {stream!r} must have dtype {_STANDARD[stream]}, got {dtype}")
        self._in_order()  # before any look into the file too: a lookup can make HDF5 flush and allocate
        if stream in self._file:
            raise ValueError(f"{stream!r} already exists in the file and is not an event stream")
        state = _Stream(self._file.create_group(stream), dtype, self._filters)
        self._streams[stream] = state
        return state

    def wait(self) -> None:
        """Block until the events appended so far are compressed and written (but the last partial
        HDF5 chunk of each stream, which waits for more events or :meth:`close`); raises a failure of
        the writer thread. Returns at once without one (``background=False``)."""
        self._check_open()
        if self._worker is not None:
            self._worker.wait()

    def set_end(self, t_end_us: int) -> None:
        """Set the recording's end time; every ``ms_to_idx`` then covers [0, t_end_us]."""
        self._t_end_us = int(t_end_us)

    # -- frames, arrays, attributes -------------------------------------------------------
    def append_frame(self, name: str, image: np.ndarray, t_us: int, *, units: str | None = None,
                     meaning: str | None = None) -> None:
        """Append an (H, W) or (H, W, C) image taken at ``t_us`` to ``/frames/<name>``; ``units`` and
        ``meaning`` of the images are stored with the first one."""
        self._check_open()
        image = np.asarray(image)
        if image.ndim not in (2, 3):
            raise ValueError(f"frame {name!r}: image must be (H, W) or (H, W, C), got shape {image.shape}")
        self._in_order()
        group = self._file.require_group("frames")
        if name not in group:
            g = group.create_group(name)
            g.create_dataset("images", shape=(0, *image.shape), maxshape=(None, *image.shape), dtype=image.dtype,
                             chunks=(1, *image.shape), **_filters(self._filters, image.dtype))
            g.create_dataset("t", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(1024,))
            _describe(g["images"], units, meaning)
            _describe(g["t"], *FRAME_T_ATTRS)
        images, t = group[name]["images"], group[name]["t"]
        if image.shape != images.shape[1:] or image.dtype != images.dtype:
            raise ValueError(f"frame {name!r}: got {image.shape} {image.dtype}, "
                             f"earlier frames are {images.shape[1:]} {images.dtype}")
        n = images.shape[0]
        if n and int(t_us) <= int(t[n - 1]):
            raise ValueError(f"frame {name!r}: t={int(t_us)} us is not after the previous frame's t={int(t[n - 1])} us")
        ensure_room(self.path, image.nbytes)
        images.resize((n + 1, *image.shape))
        t.resize((n + 1,))
        images[n], t[n] = image, int(t_us)
        _settle(images, t)

    def write_array(self, path_in_file: str, array: np.ndarray, attrs: dict | None = None, *,
                    units: str | None = None, meaning: str | None = None) -> None:
        """Store ``array`` as a dataset at ``path_in_file`` (e.g. ``"thresholds/on"``) with its
        ``units`` and ``meaning`` (attributes) and any other ``attrs``."""
        self._check_open()
        self._in_order()
        if path_in_file in self._file:
            raise ValueError(f"{path_in_file!r} already exists in {self.path}")
        if path_in_file.strip("/") in ("ms_to_idx", "t_offset"):
            raise ValueError(f"{path_in_file!r} at the root is reserved for the DSEC layout of the brightness stream")
        array = np.asarray(array)
        ensure_room(self.path, array.nbytes)
        opts = _filters(self._filters, array.dtype) if array.ndim and array.size else {}
        dataset = self._file.create_dataset(path_in_file, data=array, **opts)
        _settle(dataset)
        _describe(dataset, units, meaning)
        self.set_attrs(path_in_file, **(attrs or {}))

    def set_attrs(self, group_path: str, **attrs: object) -> None:
        """Set attributes on a group (created if missing) or an existing dataset."""
        self._check_open()
        self._in_order()
        obj = self._file[group_path] if group_path in self._file else self._file.require_group(group_path)
        for key, value in attrs.items():
            if value is None or isinstance(value, dict):
                raise TypeError(f"attribute {key!r} of {group_path!r}: cannot store {type(value).__name__} in HDF5")
            obj.attrs[key] = value

    # -- finishing -------------------------------------------------------------------
    def close(self, t_end_us: int | None = None, *, before_commit: Callable[[Path], object] | None = None) -> None:
        """Finalise ``ms_to_idx``, mark the file complete and rename it onto ``path``.

        ``before_commit(tmp)`` is called with the finished, closed file under its temporary name before
        the rename: whatever else must succeed for the output to count (reading it back, a summary) runs
        there, so if it raises an earlier file at ``path`` is left as it was.
        """
        if self.closed:
            return
        try:
            if self._worker is not None:
                self._worker.join()  # the queued chunks are written
                self._worker.check()
            self._finalise(self._t_end_us if t_end_us is None else int(t_end_us))
            close_h5(self._file, self.path)  # flushed first: a full disk fails with the file still whole
            if before_commit is not None:
                before_commit(self._tmp)
            self._stage.commit()
        except BaseException:
            self.abort()
            raise
        log.debug("wrote %s", self.path)

    def _finalise(self, t_end_us: int | None) -> None:
        last = max((s.last_t or 0 for s in self._streams.values()), default=0)
        if t_end_us is None:
            t_end_us = last
        if t_end_us < last:
            raise ValueError(f"{self.path}: t_end_us={t_end_us} is before the last event at t={last} us")
        n_ms = -(-t_end_us // 1000) + 1  # k = 0 .. ceil(t_end_ms)
        for state in self._streams.values():
            state.flush()
            if state.n_ms < n_ms:
                state.extend_ms(np.full(n_ms - state.n_ms, state.n, dtype=np.int64))
        if "events" in self._streams:  # DSEC's root layout for the brightness stream
            for name in ("ms_to_idx", "t_offset"):
                if name in self._file:
                    raise ValueError(f"{self.path}: {name!r} at the root is reserved for the DSEC layout")
            self._file["ms_to_idx"] = self._streams["events"].ms  # a hard link: the same dataset
            offset = self._file.create_dataset("t_offset", data=np.int64(0))
            _describe(offset, *T_OFFSET_ATTRS)
        self._file.attrs["t_end_us"] = np.int64(t_end_us)
        self._file.attrs["complete"] = True

    def abort(self) -> None:
        """Stop the writer thread (dropping what it has not written), close and delete the temporary
        file; ``path`` is left untouched."""
        worker = getattr(self, "_worker", None)
        if worker is not None:
            worker.join(cancel=True)
        discard_h5(getattr(self, "_file", None))  # a failed write (full disk) must not leave HDF5 half closed
        self._stage.discard()
        self._file = None
