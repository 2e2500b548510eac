"""Storage of one event stream in a gevsim HDF5 file, the writer's side: its datasets, their ``units`` and
``meaning`` attributes, and writes in whole chunks (see :mod:`gevsim.io.hdf5`, which re-exports these names)."""

from __future__ import annotations

import h5py
import numpy as np

from gevsim.io.checks import BOOL_ATTR

#: Events per HDF5 chunk of every event column.
CHUNK = 2**16

#: units and meaning of the event fields: field -> (units, meaning); "p" by the field's dtype kind.
FIELD_ATTRS = {
    "x": ("px", "pixel column, 0 = left"),
    "y": ("px", "pixel row, 0 = top"),
    "t": ("us", "timestamp in microseconds from the start of the recording (plus t_offset where there is one)"),
    ("p", "b"): ("1", "polarity: 1 = ON (log intensity rose by the ON threshold), 0 = OFF (fell by the OFF "
                      "threshold); stored as uint8, read as bool"),
    ("p", "i"): ("1", "gradient event: +1 or -1, from the previous and new ternary gradient state "
                      "(Lehtonen et al., Table 1)"),
    "axis": ("1", "comparator axis: 0 = X (G_X = I(x+1, y) - I(x, y)), 1 = Y (G_Y = I(x, y+1) - I(x, y))"),
}
MS_TO_IDX_ATTRS = ("index", "ms_to_idx[k] = index of the first event with t >= k * 1000 us (DSEC)")
T_OFFSET_ATTRS = ("us", "added to events/t for absolute time (DSEC); 0: timestamps count from the start "
                        "of the recording")
FRAME_T_ATTRS = ("us", "time of each image")


def _field_attrs(name: str, dtype: np.dtype, stream: str) -> tuple[str, str]:
    return FIELD_ATTRS.get(name) or FIELD_ATTRS.get((name, dtype.kind)) or (
        "1", f"field {name!r} of the {stream!r} events (no standard meaning)")


def _describe(obj, units: str | None, meaning: str | None) -> None:
    if units is not None:
        obj.attrs["units"] = str(units)
    if meaning is not None:
        obj.attrs["meaning"] = str(meaning)


def _settle(*datasets: h5py.Dataset) -> None:
    """Write the datasets' cached chunks to the file now (HDF5's H5Dflush). A chunk gets its place in the file
    when it leaves the dataset's chunk cache, which is when the dataset closes unless it is flushed first, and a
    dataset closes when its last handle is freed: a handle held a moment longer (a thread that samples the
    stack, as Dask's profiler does) changed the order of the frames' chunks in the file (issue 37:
    ``benchmarks/layout_determinism.py``). Flushed here, the layout follows the writes alone."""
    for ds in datasets:
        if ds.chunks is not None:
            ds.flush()


class _Stream:
    """One event stream: its datasets, and the caller's view (events accepted, last time, ms_to_idx
    entries issued) and the writer's (events written, a partial chunk waiting for more)."""

    def __init__(self, group: h5py.Group, dtype: np.dtype, filters: dict):
        self.dtype, self.n, self.n_ms = dtype, 0, 0
        self.last_t: int | None = None
        group.attrs["kind"] = "events"
        group.attrs["fields"] = list(dtype.names or ())
        self.fields = {}
        stream = group.name.lstrip("/")
        for name in dtype.names or ():
            boolean = dtype[name] == np.bool_
            disk = np.dtype(np.uint8 if boolean else dtype[name])
            # Whole chunks are written at once: no chunk cache (1 byte holds none), so HDF5 compresses
            # them in the write call, in the writer thread, not later when the file is closed.
            ds = group.create_dataset(name, shape=(0,), maxshape=(None,), dtype=disk, chunks=(CHUNK,),
                                      rdcc_nbytes=1, **_filters(filters, disk))
            if boolean:
                ds.attrs[BOOL_ATTR] = "bool"
            _describe(ds, *_field_attrs(name, dtype[name], stream))
            self.fields[name] = ds
        self.ms = group.create_dataset("ms_to_idx", shape=(0,), maxshape=(None,), dtype=np.int64,
                                       chunks=(4096,), **_filters(filters, np.dtype(np.int64)))
        _describe(self.ms, *MS_TO_IDX_ATTRS)
        # Writer side (the writer thread's alone while it runs).
        self.written, self.written_ms, self.pending = 0, 0, 0
        self.buffer = {name: np.empty(CHUNK, ds.dtype) for name, ds in self.fields.items()}

    def write(self, events: np.ndarray, ms: np.ndarray) -> None:
        """Store ``events`` after those written so far and ``ms`` after the ms_to_idx entries: whole
        chunks go to the file, a partial one waits in the buffer for the next call or :meth:`flush`."""
        n, i = len(events), 0
        if self.pending:  # top up the waiting chunk
            i = min(CHUNK - self.pending, n)
            for name, buf in self.buffer.items():
                buf[self.pending:self.pending + i] = events[name][:i]  # bool -> uint8 0/1
            self.pending += i
            if self.pending == CHUNK:
                self._put(self.buffer, CHUNK)
                self.pending = 0
        whole = (n - i) // CHUNK * CHUNK
        if whole:
            self._put({name: events[name][i:i + whole] for name in self.fields}, whole)
            i += whole
        if i < n:
            for name, buf in self.buffer.items():
                buf[:n - i] = events[name][i:]
            self.pending = n - i
        if len(ms):
            self.ms.resize((self.written_ms + len(ms),))
            self.ms[self.written_ms:] = ms
            self.written_ms += len(ms)

    def flush(self) -> None:
        """Write the partial chunk waiting in the buffer."""
        if self.pending:
            self._put({name: buf[:self.pending] for name, buf in self.buffer.items()}, self.pending)
            self.pending = 0

    def _put(self, columns: dict[str, np.ndarray], n: int) -> None:
        n0, n1 = self.written, self.written + n
        for name, ds in self.fields.items():
            ds.resize((n1,))
            ds[n0:n1] = np.ascontiguousarray(columns[name], dtype=ds.dtype)
        self.written = n1

    def extend_ms(self, values: np.ndarray) -> None:
        """Append ms_to_idx entries directly (the writer thread is idle)."""
        self.ms.resize((self.written_ms + len(values),))
        self.ms[self.written_ms:] = values
        self.written_ms += len(values)
        self.n_ms += len(values)


def _filters(filters: dict, dtype: np.dtype) -> dict:
    """h5py's filter arguments for a dataset of ``dtype``: the shuffle only where items have several bytes."""
    return {**filters, "shuffle": dtype.itemsize > 1}
