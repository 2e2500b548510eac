"""One validation of every event file we read (issue 24): an event file is untrusted input.

Compiled kernels index arrays with the x, y, axis and p of the events and do not check them; exports
copy them. So :class:`~gevsim.io.hdf5.EventReader` checks each event stream whole, once, the first time
it is used, before any of its events reaches a caller, and each frame stream when it is read:

- root attributes: ``width`` and ``height`` integers in [1, :data:`MAX_SIZE_PX`] (x and y are int16),
  ``t_end_us`` an integer in [0, :data:`MAX_T_END_US`], ``seed`` an integer, texts are text;
- a stream's ``fields`` attribute names its 1-D numeric columns, all of one length, fully stored (no
  unwritten chunk read back as zeros), with the dtypes of a brightness (``x y t p``) or gradient
  (``x y t p axis``) stream (:mod:`gevsim.events.types`). Any group of ``kind`` ``"events"`` is a stream
  to view and export (issue 36, item 3): one named ``events`` or ``gradient_events``, or whose
  ``fields`` are exactly a standard stream's names, is checked as one; any other (other columns, no
  ``p``, no ``fields``) is left out (:func:`left_out`: the reader says so in an INFO line), never
  passed on unchecked;
- ``t`` is sorted and within [0, t_end_us]; x in [0, width), y in [0, height); a gradient ``axis`` is
  0 or 1 and its ``p`` +1 or -1; a polarity stored as uint8 is 0 or 1;
- ``ms_to_idx`` has ``ceil(t_end_us / 1000) + 1`` entries, each the index of the first event at or
  after its millisecond, as :class:`~gevsim.io.hdf5.EventWriter` writes it;
- frames: images (N, height, width[, C]) of numbers with N increasing times within [0, t_end_us];
  float images finite;
- every dataset read decompresses (a damaged chunk makes HDF5 raise OSError).

A failure is a :class:`~gevsim.errors.ConfigError` naming the file, the dataset or attribute and the bad
value (the CLI prints one line, exit 2). Streams are read :data:`BLOCK` events at a time, so the check
needs memory for one block (events, and ``ms_to_idx`` entries) and the milliseconds that hold events,
whatever the length of the recording.
"""

from __future__ import annotations

import h5py
import numpy as np

from gevsim.errors import ConfigError
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE, check_events
from gevsim.timebase import MAX_DURATION_S

__all__ = ["BLOCK", "BOOL_ATTR", "MAX_SIZE_PX", "MAX_T_END_US", "STANDARD", "bounded_int", "check_stream",
           "left_out", "read", "read_frames", "text"]

#: Marks a dataset stored as uint8 0/1 that holds a bool field.
BOOL_ATTR = "numpy_dtype"
#: Streams that must have a standard dtype; so must any stream with exactly the field names of one.
STANDARD = {"events": BRIGHTNESS_DTYPE, "gradient_events": GRADIENT_DTYPE}
#: Largest width or height: x and y are int16.
MAX_SIZE_PX = 2**15
#: Longest recording read, one day, as long as gevsim writes (:data:`gevsim.timebase.MAX_DURATION_S`;
#: ms_to_idx, 8 bytes a millisecond, 0.7 GB, is checked a block at a time).
MAX_T_END_US = int(MAX_DURATION_S) * 10**6
#: Events per block of the stream check.
BLOCK = 2**20


def _text(value: object) -> str | None:
    """An untrusted attribute as text, or None when it is not a string (an array, a number)."""
    return value if isinstance(value, str) else None


def _show(value: object) -> str:
    if isinstance(value, np.ndarray | np.generic):
        value = value.tolist()
    text = repr(value).replace("\n", " ")
    return text if len(text) <= 60 else text[:57] + "..."


def read(ds: h5py.Dataset, sel: object = (), *, source: str) -> np.ndarray:
    """``ds[sel]``; data HDF5 cannot read back (a damaged compressed chunk) is a ConfigError naming the
    dataset."""
    try:
        return ds[sel]
    except OSError as exc:
        raise ConfigError(f"cannot read the data, the file is damaged ({_show(str(exc))})", source=source,
                          key=ds.name) from None


def bounded_int(value: object, name: str, lo: int, hi: int, source: str) -> int:
    """A root attribute that must be an integer in [lo, hi]."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer) or not lo <= int(value) <= hi:
        raise ConfigError(f"must be an integer in [{lo}, {hi}], got {_show(value)}", source=source,
                          key=f"root attribute {name!r}")
    return int(value)


def text(value: object, name: str, source: str) -> str:
    """A root attribute that must be text."""
    if not isinstance(value, str):
        raise ConfigError(f"must be text, got {_show(value)}", source=source, key=f"root attribute {name!r}")
    return value


def _stored(ds: h5py.Dataset) -> bool:
    """Every element of a dataset is in the file (a chunk never written reads back as zeros)."""
    if ds.size == 0:
        return True
    if ds.chunks is None:
        return ds.id.get_storage_size() >= ds.size * ds.dtype.itemsize
    per = [-(-n // c) for n, c in zip(ds.shape, ds.chunks)]
    return ds.id.get_num_chunks() >= int(np.prod(per))


def _column(group: h5py.Group, name: str, source: str, *, integer: bool = False) -> h5py.Dataset:
    """A fully stored 1-D dataset of numbers (of integers with ``integer``) in ``group``."""
    ds = group.get(name) if isinstance(name, str) and name and "/" not in name else None
    where = f"{group.name}/{name}"
    if not isinstance(ds, h5py.Dataset):
        raise ConfigError("is missing (or not a dataset)", source=source, key=where)
    kinds = "iu" if integer else "biuf"
    if ds.ndim != 1 or ds.dtype.kind not in kinds or ds.dtype.shape != ():
        raise ConfigError(f"must be a 1-D array of {'integers' if integer else 'numbers'}, got shape {ds.shape} "
                          f"of {ds.dtype}", source=source, key=where)
    if not _stored(ds):
        raise ConfigError("has parts that were never written (truncated or damaged file)", source=source, key=where)
    return ds


def _field_names(group: h5py.Group) -> list[str] | None:
    """The ``fields`` attribute of a stream as a list of texts, or None where it is not one."""
    fields = group.attrs.get("fields")
    if not isinstance(fields, np.ndarray) or fields.ndim != 1 or not all(isinstance(n, str) for n in fields):
        return None
    return [str(n) for n in fields]


def _standard_for(name: str, fields: list[str] | None) -> np.dtype | None:
    """The standard dtype a stream must have: by its name, else by its field names (as a set); None if neither."""
    return STANDARD.get(name) or next((d for d in STANDARD.values() if fields is not None
                                       and len(fields) == len(d.names or ()) and set(d.names or ()) == set(fields)),
                                      None)


def left_out(group: h5py.Group) -> str | None:
    """Why a group of ``kind`` ``"events"`` is not a stream (its columns are not a brightness or gradient
    stream's), or None for a stream (which :func:`check_stream` checks whole). Reads attributes only."""
    fields = _field_names(group)
    if _standard_for(group.name.lstrip("/"), fields) is not None:
        return None
    return (f"its columns ('fields' attribute {_show(group.attrs.get('fields'))}) are not those of a brightness "
            "(x y t p) or gradient (x y t p axis) stream")


def stream_dtype(group: h5py.Group, *, source: str) -> np.dtype:
    """The in-memory dtype of a stream, from its ``fields`` attribute and columns, checked."""
    names = _field_names(group) or []
    want = _standard_for(group.name.lstrip("/"), names)
    if (want is None or not names or len(set(names)) != len(names) or "t" not in names
            or "ms_to_idx" in names):
        raise ConfigError(f"must list the stream's columns, those of a brightness (x y t p) or gradient "
                          f"(x y t p axis) stream, got {_show(group.attrs.get('fields'))}", source=source,
                          key=f"{group.name} attribute 'fields'")
    columns = {name: _column(group, name, source, integer=name == "t") for name in names}
    dtype = np.dtype([(name, np.bool_ if _text(ds.attrs.get(BOOL_ATTR)) == "bool" else ds.dtype)
                      for name, ds in columns.items()])
    if dtype != want:
        raise ConfigError(f"the columns must have dtype {want}, got {dtype}", source=source, key=group.name)
    lengths = {name: ds.shape[0] for name, ds in columns.items()}
    if len(set(lengths.values())) > 1:
        raise ConfigError(f"columns of different lengths: {lengths}", source=source, key=group.name)
    return dtype


def check_stream(group: h5py.Group, *, shape: tuple[int, int], t_end_us: int, source: str) -> np.dtype:
    """Check one event stream whole (see the module's notes); returns its in-memory dtype."""
    dtype = stream_dtype(group, source=source)
    names = dtype.names or ()
    n = group["t"].shape[0]
    ms_ds = _column(group, "ms_to_idx", source, integer=True)
    n_ms = -(-t_end_us // 1000) + 1
    if ms_ds.shape[0] != n_ms:
        raise ConfigError(f"has {ms_ds.shape[0]} entries, but t_end_us = {t_end_us} needs {n_ms} (one a "
                          f"millisecond)", source=source, key=ms_ds.name)
    bins, counts = [], []  # the milliseconds k (t in [(k - 1) ms, k ms)) that hold events, and how many
    last = 0
    for i0 in range(0, n, BLOCK):
        cols = {name: read(group[name], slice(i0, i0 + BLOCK), source=source) for name in names}
        t = cols["t"]
        if t.min() < 0 or t.max() > t_end_us:
            bad = int(t[(t < 0) | (t > t_end_us)][0])
            raise ConfigError(f"t = {bad} us lies outside the recording [0, t_end_us = {t_end_us}]",
                              source=source, key=f"{group.name}/t")
        t = t.astype(np.int64)
        down = np.flatnonzero(np.diff(t, prepend=last) < 0)
        if down.size:
            i = int(down[0])
            before = last if i == 0 else int(t[i - 1])
            raise ConfigError(f"not sorted: t[{i0 + i}] = {int(t[i])} us follows {before} us", source=source,
                              key=f"{group.name}/t")
        last = int(t[-1])
        k, c = np.unique(t // 1000 + 1, return_counts=True)
        bins.append(k)
        counts.append(c)
        for name in names:
            if dtype[name] == np.bool_ and cols[name].dtype != np.bool_ and np.any(cols[name] > 1):
                raise ConfigError(f"a polarity stored as 0 or 1 holds {int(cols[name].max())}", source=source,
                                  key=f"{group.name}/{name}")
        ev = np.empty(len(t), dtype)  # a standard dtype (stream_dtype): the kernels' own check
        for name in names:
            ev[name] = cols[name]
        try:
            check_events(ev, name=group.name, shape=shape)
        except ValueError as exc:
            raise ConfigError(f"corrupt event data: {exc}", source=source) from None
    _check_ms_to_idx(ms_ds, np.concatenate(bins or [np.zeros(0, np.int64)]),
                     np.cumsum(np.concatenate(counts or [np.zeros(0, np.int64)])), source=source)
    return dtype


def _check_ms_to_idx(ms_ds: h5py.Dataset, bins: np.ndarray, before: np.ndarray, *, source: str) -> None:
    """Check ``ms_to_idx`` against the events, a block at a time: entry j must be the number of events before
    j ms, ``before[i]`` counting those up to millisecond bin ``bins[i]`` (increasing; a bin may repeat across
    event blocks). Memory: the bins that hold events and one block, not a day's 86.4 M entries three times."""
    for j0 in range(0, ms_ds.shape[0], BLOCK):
        ms = read(ms_ds, slice(j0, j0 + BLOCK), source=source)
        j = np.arange(j0, j0 + len(ms))
        i = np.searchsorted(bins, j, side="right") - 1  # the last bin at or before j
        expected = np.where(i >= 0, before[np.maximum(i, 0)] if len(before) else 0, 0)
        wrong = np.flatnonzero(ms != expected)
        if wrong.size:
            k0 = int(wrong[0])
            raise ConfigError(f"entry {j0 + k0} is {_show(ms[k0])}, but t puts {int(expected[k0])} events before "
                              f"{j0 + k0} ms", source=source, key=ms_ds.name)


def read_frames(group: object, *, shape: tuple[int, int], t_end_us: int, source: str) -> tuple[np.ndarray, np.ndarray]:
    """``(images, t_us)`` of a frame stream ``/frames/<name>``, checked (see the module's notes)."""
    where = getattr(group, "name", "frames")
    if not isinstance(group, h5py.Group):
        raise ConfigError("is not a frame stream (a group with images and t)", source=source, key=where)
    images = group.get("images")
    if (not isinstance(images, h5py.Dataset) or images.ndim not in (3, 4) or images.shape[1:3] != tuple(shape)
            or images.dtype.kind not in "biuf" or images.dtype.shape != ()):
        got = f"shape {images.shape} of {images.dtype}" if isinstance(images, h5py.Dataset) else "no dataset"
        raise ConfigError(f"must be (N, {shape[0]}, {shape[1]}[, C]) numbers, got {got}", source=source,
                          key=f"{where}/images")
    t_ds = _column(group, "t", source, integer=True)
    if t_ds.shape[0] != images.shape[0]:
        raise ConfigError(f"has {t_ds.shape[0]} times for {images.shape[0]} images", source=source, key=t_ds.name)
    t = read(t_ds, source=source)
    if t.size and (t.min() < 0 or t.max() > t_end_us):
        raise ConfigError(f"holds {int(t[(t < 0) | (t > t_end_us)][0])} us, outside the recording "
                          f"[0, t_end_us = {t_end_us}]", source=source, key=t_ds.name)
    down = np.flatnonzero(np.diff(t.astype(np.int64)) <= 0)
    if down.size:
        i = int(down[0])
        raise ConfigError(f"times must increase: t[{i + 1}] = {int(t[i + 1])} us follows {int(t[i])} us",
                          source=source, key=t_ds.name)
    if images.size and not _stored(images):
        raise ConfigError("has parts that were never written (truncated or damaged file)", source=source,
                          key=images.name)
    data = read(images, source=source)
    if data.dtype.kind == "f" and not np.all(np.isfinite(data)):
        raise ConfigError(f"holds {int(np.count_nonzero(~np.isfinite(data)))} values that are not finite "
                          "(NaN or inf)", source=source, key=images.name)
    return data, t.astype(np.int64)
