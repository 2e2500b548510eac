"""Reading a gevsim HDF5 event file (the layout is described in :mod:`gevsim.io.hdf5`, which re-exports
:class:`EventReader`). Every value read is checked before it is used (:mod:`gevsim.io.checks`)."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import h5py
import numpy as np
from numpy.typing import ArrayLike

from gevsim.errors import ConfigError, suggest
from gevsim.io import checks
from gevsim.io.sealed import check_sealed

log = logging.getLogger(__name__)

FORMAT = "gevsim-events-2"
#: Formats EventReader reads: 1 stored the polarity as an HDF5 bool enum and had no root ms_to_idx.
READABLE_FORMATS = ("gevsim-events-1", FORMAT)
#: Default bound on the events of one window of :meth:`EventReader.windows` (~13 MiB of brightness events).
WINDOW_EVENTS = 2**20


#: Streams already checked, per file identity (see EventReader); bounded: cleared when it grows past 256 files.
_CHECKED: dict[tuple, dict[str, np.dtype]] = {}
#: Streams left out and said so (one INFO line per file version and stream); bounded like _CHECKED.
_TOLD: set[tuple] = set()


def _identity(path: Path) -> tuple | None:
    """What identifies one version of a file: its real path, device, inode, size and modification time."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    if len(_CHECKED) > 256:
        _CHECKED.clear()
    if len(_TOLD) > 1024:
        _TOLD.clear()
    return (os.path.realpath(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def _is_text(value: object, expected: str) -> bool:
    """Whether an untrusted attribute is the text ``expected`` (an array or number is not)."""
    return isinstance(value, str) and value == expected


class EventReader:
    """Read a complete gevsim HDF5 event file.

    Its streams (:attr:`streams`) are the groups whose ``kind`` is ``"events"`` and whose columns are those
    of a brightness or gradient stream; any other such group is left out with one INFO line. A stream is
    checked whole before any of its events is returned (:mod:`gevsim.io.checks`).

    Raises
    ------
    ConfigError
        If ``path`` is missing, not HDF5, not a gevsim file, incomplete, or holds data stored outside
        it (:mod:`gevsim.io.sealed`; checked when it is opened, before any data is read).
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        src = str(self.path)
        if not self.path.is_file():
            raise ConfigError("no such file", source=src)
        try:
            self._file = _open_shared(self.path)
        except OSError as exc:
            raise ConfigError(f"not an HDF5 file ({exc})", source=src) from None
        attrs = self._file.attrs
        fmt, complete = attrs.get("format"), attrs.get("complete", False)  # untrusted: arrays, bytes, anything
        if not isinstance(fmt, str) or fmt not in READABLE_FORMATS:
            self._file.close()
            raise ConfigError(f"not a gevsim event file (format attribute {fmt!r}, "
                              f"expected one of {', '.join(map(repr, READABLE_FORMATS))})", source=src)
        if not isinstance(complete, (bool, np.bool_)) or not complete:
            self._file.close()
            raise ConfigError("incomplete gevsim event file: the writer did not finish", source=src)
        try:
            check_sealed(self._file, source=src)
        except ConfigError:
            self._file.close()
            raise
        self._ms_cache: dict[str, np.ndarray] = {}
        # Streams checked whole (gevsim.io.checks), with their dtypes: shared by every reader of this very file
        # (same inode, size and modification time), so a file read again (a reconstruction per method, an
        # export's child, a run's summary) is not checked again.
        self._identity = _identity(self.path)
        self._dtypes: dict[str, np.dtype] = _CHECKED.setdefault(self._identity, {}) if self._identity else {}
        self._streams: tuple[str, ...] | None = None
        self._left_out: dict[str, str] = {}

    def __enter__(self) -> EventReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._file.close()

    def _root(self, name: str):
        """A root attribute; a missing one is an input error naming the file and the attribute."""
        if name not in self._file.attrs:
            raise ConfigError(f"root attribute {name!r} is missing: not a file written by gevsim, or damaged",
                              source=str(self.path))
        return self._file.attrs[name]

    # Attributes are untrusted too: typed and bounded (gevsim.io.checks).
    width = property(lambda self: checks.bounded_int(self._root("width"), "width", 1, checks.MAX_SIZE_PX,
                                                     str(self.path)))
    height = property(lambda self: checks.bounded_int(self._root("height"), "height", 1, checks.MAX_SIZE_PX,
                                                      str(self.path)))
    config_toml = property(lambda self: checks.text(self._root("config_toml"), "config_toml", str(self.path)))
    seed = property(lambda self: checks.bounded_int(self._root("seed"), "seed", -2**63, 2**64 - 1, str(self.path)))
    gevsim_version = property(lambda self: checks.text(self._root("gevsim_version"), "gevsim_version",
                                                       str(self.path)))
    t_end_us = property(lambda self: checks.bounded_int(self._root("t_end_us"), "t_end_us", 0, checks.MAX_T_END_US,
                                                        str(self.path)))

    @property
    def attrs(self) -> dict:
        """All root attributes."""
        return dict(self._file.attrs)

    @property
    def streams(self) -> tuple[str, ...]:
        """Names of the event streams in the file (sorted): groups of ``kind`` ``"events"``, except those
        left out for their columns (:func:`gevsim.io.checks.left_out`, said once in an INFO line)."""
        if self._streams is None:
            kept = []
            for name, group in self._file.items():
                if not isinstance(group, h5py.Group) or not _is_text(group.attrs.get("kind"), "events"):
                    continue
                why = checks.left_out(group)
                if why is None:
                    kept.append(name)
                    continue
                self._left_out[name] = why
                if (self._identity, name) not in _TOLD:
                    _TOLD.add((self._identity, name))
                    log.info("%s: stream %r left out: %s", self.path, name, why)
            self._streams = tuple(sorted(kept))
        return self._streams

    @property
    def left_out(self) -> dict[str, str]:
        """Groups of ``kind`` ``"events"`` that are not streams: name -> why."""
        _ = self.streams  # sorts the groups into streams and left-out ones
        return dict(self._left_out)

    @property
    def frame_names(self) -> tuple[str, ...]:
        return tuple(sorted(self._file["frames"])) if isinstance(self._file.get("frames"), h5py.Group) else ()

    def _stream(self, stream: str) -> h5py.Group:
        if stream not in self.streams and stream in self._left_out:
            raise ConfigError(f"stream {stream!r} is left out: {self._left_out[stream]}", source=str(self.path))
        if stream not in self.streams:
            raise ConfigError(f"no event stream {stream!r}{suggest(stream, self.streams)}; "
                              f"streams: {', '.join(self.streams) or 'none'}", source=str(self.path))
        if stream not in self._dtypes:  # the whole stream is checked once, before any of it is used
            self._dtypes[stream] = checks.check_stream(self._file[stream], shape=(self.height, self.width),
                                                       t_end_us=self.t_end_us, source=str(self.path))
        return self._file[stream]

    def dtype(self, stream: str = "events") -> np.dtype:
        self._stream(stream)
        return self._dtypes[stream]

    def ms_to_idx(self, stream: str = "events") -> np.ndarray:
        return self._stream(stream)["ms_to_idx"][:]

    def count(self, stream: str = "events") -> int:
        """Number of events in ``stream``."""
        return int(self._stream(stream)["t"].shape[0])

    def first_t_us(self, stream: str = "events") -> int | None:
        """Timestamp (us) of the first event of ``stream``; None if it has none."""
        t = self._stream(stream)["t"]
        return int(t[0]) if t.shape[0] else None

    def index_bounds(self, stream: str, t_us: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``(lo, hi)`` on the index of the first event of ``stream`` with time >= each of
        ``t_us`` (>= 0), from ``ms_to_idx`` alone (exact at whole milliseconds): ``hi[j] - lo[i]``
        bounds the number of events in ``[t_us[i], t_us[j])``."""
        t = np.asarray(t_us, dtype=np.int64)
        if t.size and t.min() < 0:
            raise ValueError(f"times must be >= 0 us, got {int(t.min())} us")
        if stream not in self._ms_cache:
            self._ms_cache[stream] = self.ms_to_idx(stream)
        ms, n = self._ms_cache[stream], self.count(stream)
        if not len(ms):
            return np.zeros(t.shape, np.int64), np.full(t.shape, n, np.int64)
        lo = ms[np.minimum(t // 1000, len(ms) - 1)]
        k = -(-t // 1000)
        hi = np.where(k < len(ms), ms[np.minimum(k, len(ms) - 1)], n)
        return lo.astype(np.int64), hi.astype(np.int64)

    def windows(self, stream: str, t_start_us: int, t_end_us: int, *,
                max_events: int | None = None) -> list[tuple[int, int]]:
        """Consecutive time windows ``[a, b)`` (us) covering ``[t_start_us, t_end_us)``, each holding
        at most ``max_events`` events of ``stream`` (judged from ``ms_to_idx``, so inner
        boundaries fall on whole milliseconds: a millisecond holding more events is one window).
        Reading a stream window by window bounds memory whatever the duration or event rate.
        ``max_events`` defaults to :data:`WINDOW_EVENTS` (read at the call)."""
        if max_events is None:
            max_events = WINDOW_EVENTS  # read at the call, where callers and tests set it
        if not isinstance(max_events, int | np.integer) or max_events < 1:
            raise ValueError(f"max_events must be a positive integer, got {max_events!r}")
        t0, t1 = int(t_start_us), int(t_end_us)
        if t1 <= t0:
            return []
        lo, hi = self.index_bounds(stream, [t0, t1])
        ms, top = self._ms_cache[stream], int(hi[1])
        out, a, base = [], t0, int(lo[0])
        while a < t1:
            if top - base <= max_events:
                b = t1
            else:  # the furthest whole millisecond that keeps the window within max_events
                b = (int(np.searchsorted(ms, base + max_events, side="right")) - 1) * 1000
                b = min(max(b, (a // 1000 + 1) * 1000), t1)
            out.append((a, b))
            a = b
            base = int(self.index_bounds(stream, [a])[0][0])
        return out

    def read(self, stream: str = "events", t_start_us: int | None = None, t_end_us: int | None = None) -> np.ndarray:
        """Events of ``stream`` with ``t_start_us <= t < t_end_us`` (``None``: unbounded)."""
        group = self._stream(stream)
        dtype = self.dtype(stream)
        ms, t_ds = group["ms_to_idx"], group["t"]
        n, n_ms = t_ds.shape[0], ms.shape[0]
        lo = 0
        if t_start_us is not None:  # ms_to_idx[floor(t_start/1000)] <= first index >= t_start
            k = int(t_start_us) // 1000
            lo = 0 if k < 0 else int(ms[min(k, n_ms - 1)])
        hi = n
        if t_end_us is not None:  # ms_to_idx[ceil(t_end/1000)] >= first index >= t_end
            k = -(-int(t_end_us) // 1000)
            hi = 0 if k < 0 else (int(ms[k]) if k < n_ms else n)
        hi = max(hi, lo)
        t = t_ds[lo:hi]
        a = lo + (int(np.searchsorted(t, t_start_us, side="left")) if t_start_us is not None else 0)
        b = lo + (int(np.searchsorted(t, t_end_us, side="left")) if t_end_us is not None else len(t))
        b = max(a, b)
        out = np.empty(b - a, dtype=dtype)
        for name in dtype.names or ():  # values checked by _stream (compiled kernels index with them)
            out[name] = t[a - lo:b - lo] if name == "t" else group[name][a:b]  # uint8 0/1 -> bool where marked
        return out

    def frames(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """``(images, t_us)`` of the frame stream ``name``."""
        if name not in self.frame_names:
            raise ConfigError(f"no frames {name!r}{suggest(name, self.frame_names)}; "
                              f"frames: {', '.join(self.frame_names) or 'none'}", source=str(self.path))
        return checks.read_frames(self._file["frames"][name], shape=(self.height, self.width),
                                  t_end_us=self.t_end_us, source=str(self.path))

    def __contains__(self, path: str) -> bool:
        return path in self._file

    def array(self, path: str) -> np.ndarray:
        """The dataset stored at ``path`` (see :meth:`EventWriter.write_array`)."""
        if path not in self._file or not isinstance(self._file[path], h5py.Dataset):
            raise ConfigError(f"no dataset {path!r}", source=str(self.path))
        return checks.read(self._file[path], source=str(self.path))

    def array_attrs(self, path: str) -> dict:
        return dict(self._file[path].attrs)


def _open_shared(path: Path) -> h5py.File:
    """Open for reading with HDF5's file locking as h5py does by default, so that a user's plain
    ``h5py.File(path)`` and a reader can be open at once (HDF5 refuses a second open in one process with
    other locking flags); where the lock cannot be had (a writer's check of its own finished stage,
    ``EventWriter.close(before_commit=...)``, reads it while gevsim's stage lock holds it; a handle opened
    with ``locking=False``), without it: complete files are never written again."""
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        if "lock" not in str(exc).lower():
            raise
        return h5py.File(path, "r", locking=False)
