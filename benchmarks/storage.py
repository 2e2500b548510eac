"""Compact event storage: bytes per event, write throughput, and background writes overlapping emulation.

Usage: python benchmarks/storage.py [--repeat 5] [--chunks 10] [--sections bytes,writer,burn,emulation]

Streams (346x260 px):

- ``dvs_flicker``: the scikit-image ``camera`` photograph at ~1 klux on the chip under a 100 Hz
  square-wave lamp (+-25 %), davis346 sensor (noise on), 10 us steps, 20 ms: the DVS events (bursts
  at each lamp edge).
- ``gradient_chatter``: the gradient events of the same run (comparators chattering on pixel noise),
  the first 3 M.
- ``dvs_pan``: the ``flicker_pan`` input of ``event_throughput.py`` (the ``brick`` texture panning 1 px
  per 500 us step under the same lamp, noise-free pixel), 40 steps: DVS events everywhere.

Sections:

- ``bytes``: every column written with h5py alone (chunks of 2^16 events) for gzip levels 1, 2, 4, 6
  and lzf, without and with HDF5's shuffle filter; the narrower dtypes of DSEC's files (t uint32
  minus t_offset, x and y uint16) with gzip 1 + shuffle. Bytes per event (storage size / events) and
  write throughput on one thread (median of ``--repeat``).
- ``writer``: ``EventWriter`` (its defaults) writing each stream in appends of 100 k events,
  foreground vs background thread: M events/s from the first append to the end of ``close``.
- ``burn``: a simulated emulation loop: per chunk, a numba kernel burns the CPU (single-threaded, about
  as long as writing the chunk takes), then the chunk (500 k gradient events) is appended; the kernel
  holds the GIL (``njit``) or releases it (``nogil=True``). Wall time foreground vs background.
- ``emulation``: the real path (photoreceptor + DVS + gradient on the dvs_flicker input, chunks of
  200 steps, ``--chunks`` of them) appending both streams, 1 and 2 numba threads, foreground vs
  background; the two files' events are checked to be identical.

Runs alternate foreground and background; the tables give medians of ``--repeat`` and the ratio of
the medians. Not a timed test.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import h5py
import numba
import numpy as np
from skimage import data
from skimage.transform import resize

from gevsim.events import BrightnessEmulator, GradientEmulator
from gevsim.io.hdf5 import CHUNK, EventReader, EventWriter
from gevsim.pixel import Photoreceptor, load_preset

H, W = 260, 346
META = dict(width=W, height=H, config_toml="", seed=0)


def lamp(t):
    """100 Hz square wave, +-25 %."""
    return np.where(np.mod(t * 100.0, 1.0) < 0.5, 1.25, 0.75).astype(np.float32)


class FlickerRun:
    """Photoreceptor + DVS + gradient on the camera photograph under the square-wave lamp (davis346)."""

    def __init__(self, steps: int = 200, seed: int = 0):
        self.preset = load_preset("davis346")
        i_ref = self.preset.photoreceptor.cutoff_ref_photocurrent_a
        camera = resize(data.camera().astype(float) / 255, (H, W)) * 0.9 + 0.05
        self.base = (i_ref * camera).astype(np.float32)
        self.steps, self.dt = steps, 1e-5
        rng = np.random.default_rng(seed)
        p = self.preset
        self.pr = Photoreceptor((H, W), params=p.photoreceptor, noise=p.noise, rng=rng)
        self.dvs = BrightnessEmulator((H, W), p.events, rng=rng)
        self.grad = GradientEmulator((H, W), mismatch_sigma_ln=p.events.threshold_mismatch_ln, rng=rng)

    def chunk(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        t = self.dt * np.arange(k * self.steps + 1, (k + 1) * self.steps + 1)
        v = self.pr.process(self.base[None] * lamp(t)[:, None, None], t)
        return self.dvs.process(v, t), self.grad.process(v, t)


def pan_events(steps: int = 40) -> np.ndarray:
    preset = load_preset("davis346").ideal()
    i_ref = preset.photoreceptor.cutoff_ref_photocurrent_a
    brick = resize(data.brick().astype(float) / 255, (H, 2 * W)) * 0.9 + 0.05
    rng = np.random.default_rng(0)
    pr = Photoreceptor((H, W), params=preset.photoreceptor, noise=preset.noise, rng=rng)
    dvs = BrightnessEmulator((H, W), preset.events, rng=rng)
    out = []
    for k in range(0, steps, 10):
        n = np.arange(k, k + 10)
        t = 5e-4 * (n + 1)
        frames = np.stack([np.roll(brick, -int(j), axis=1)[:, :W] for j in n]) * lamp(t)[:, None, None]
        out.append(dvs.process(pr.process((i_ref * frames).astype(np.float32), t), t))
    return np.concatenate(out)


def streams(max_gradient: int = 3_000_000) -> dict[str, np.ndarray]:
    run = FlickerRun()
    dvs, grad = [], []
    for k in range(10):
        d, g = run.chunk(k)
        dvs.append(d)
        grad.append(g)
    return {"dvs_flicker": np.concatenate(dvs), "gradient_chatter": np.concatenate(grad)[:max_gradient],
            "dvs_pan": pan_events()}


def columns(ev: np.ndarray, *, narrow: bool = False) -> dict[str, np.ndarray]:
    """On-disk columns: bool -> uint8; with ``narrow`` DSEC's dtypes (t uint32 - t_offset, x, y uint16)."""
    out = {}
    for name in ev.dtype.names:
        a = ev[name]
        if a.dtype == np.bool_:
            a = a.astype(np.uint8)
        elif narrow and name == "t":
            a = (a - a[0]).astype(np.uint32)
        elif narrow and name in ("x", "y"):
            a = a.astype(np.uint16)
        out[name] = np.ascontiguousarray(a)
    return out


def write_columns(path: Path, cols: dict[str, np.ndarray], compression: str | None, level: int | None,
                  shuffle: bool) -> int:
    """Write the columns as h5py datasets; total storage size in bytes."""
    with h5py.File(path, "w") as f:
        for name, a in cols.items():
            f.create_dataset(name, data=a, chunks=(CHUNK,), compression=compression, compression_opts=level,
                             shuffle=shuffle and a.dtype.itemsize > 1)
        f.flush()
        return sum(f[name].id.get_storage_size() for name in cols)


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        tick = time.perf_counter()
        fn()
        times.append(time.perf_counter() - tick)
    return float(np.median(times))


def paired(run, repeat: int) -> tuple[float, float, np.ndarray]:
    """``run(background)`` -> seconds, timed ``repeat`` times each way, the order alternating:
    median foreground and background seconds and the ratio background / foreground of each pair."""
    pairs = []
    for k in range(repeat):
        order = (False, True) if k % 2 == 0 else (True, False)
        got = {bg: run(bg) for bg in order}
        pairs.append((got[False], got[True]))
    a = np.array(pairs)
    return float(np.median(a[:, 0])), float(np.median(a[:, 1])), a[:, 1] / a[:, 0]


def ratio_cell(r: np.ndarray) -> str:
    return f"{np.median(r):.2f} ({r.min():.2f}-{r.max():.2f})"


def section_bytes(evs: dict[str, np.ndarray], tmp: Path, repeat: int) -> None:
    print("\n## bytes per event and single-thread write throughput (h5py, chunks of 2^16 events)\n")
    options = [("gzip", lv) for lv in (1, 2, 4, 6)] + [("lzf", None)]
    names = list(evs)
    print("| filter | shuffle | dtypes | " + " | ".join(f"{n} B/event | {n} M ev/s" for n in names) + " |")
    print("|---|---|---|" + "---|---|" * len(names))
    rows = [(c, lv, s, False) for c, lv in options for s in (False, True)]
    rows += [("gzip", 1, True, True), (None, None, False, False)]
    for comp, level, shuffle, narrow in rows:
        cells = []
        for name in names:
            cols = columns(evs[name], narrow=narrow)
            size = write_columns(tmp / "b.h5", cols, comp, level, shuffle)
            s = median_time(lambda cols=cols: write_columns(tmp / "b.h5", cols, comp, level, shuffle), repeat)
            cells.append(f"{size / len(evs[name]):.3f} | {len(evs[name]) / s / 1e6:.1f}")
        label = "none" if comp is None else f"{comp} {level}" if level else comp
        dtypes = "t u4 - t_offset, x y u2 (DSEC)" if narrow else "as in memory"
        print(f"| {label} | {'yes' if shuffle else 'no'} | {dtypes} | " + " | ".join(cells) + " |", flush=True)
    print("\nfields of the default (gzip 1 + shuffle), B/event: " + "; ".join(
        f"{name}: " + ", ".join(f"{k} {v:.3f}" for k, v in field_sizes(evs[name], tmp).items()) for name in names))


def field_sizes(ev: np.ndarray, tmp: Path) -> dict[str, float]:
    out = {}
    for name, a in columns(ev).items():
        out[name] = write_columns(tmp / "f.h5", {name: a}, "gzip", 1, True) / len(ev)
    return out


def write_stream(path: Path, ev: np.ndarray, background: bool, name: str, step: int = 100_000) -> None:
    with EventWriter(path, background=background, **META) as w:
        for a in range(0, len(ev), step):
            w.append(name, ev[a:a + step])


def section_writer(evs: dict[str, np.ndarray], tmp: Path, repeat: int) -> None:
    print("\n## EventWriter throughput, appends of 100 k events (M events/s of the median times; "
          "time ratio background / foreground: median (min-max) of the pairs)\n")
    print("| stream | events | foreground | background | background / foreground time |")
    print("|---|---|---|---|---|")
    for name, ev in evs.items():
        stream = "gradient_events" if "axis" in ev.dtype.names else "events"

        def one(bg: bool, ev=ev, stream=stream) -> float:
            tick = time.perf_counter()
            write_stream(tmp / f"w{int(bg)}.h5", ev, bg, stream)
            return time.perf_counter() - tick

        fg, bg, r = paired(one, repeat)
        with EventReader(tmp / "w0.h5") as r0, EventReader(tmp / "w1.h5") as r1:
            assert np.array_equal(r0.read(stream), r1.read(stream)) and len(r0.read(stream)) == len(ev)
        print(f"| {name} | {len(ev) / 1e6:.2f} M | {len(ev) / fg / 1e6:.1f} | {len(ev) / bg / 1e6:.1f} | "
              f"{ratio_cell(r)} |", flush=True)


@numba.njit(cache=True)
def _burn(n):
    s = 0.0
    for i in range(n):
        s += np.sin(i * 1e-3)
    return s


@numba.njit(cache=True, nogil=True)
def _burn_nogil(n):
    s = 0.0
    for i in range(n):
        s += np.sin(i * 1e-3)
    return s


def section_burn(evs: dict[str, np.ndarray], tmp: Path, repeat: int, chunks: int) -> None:
    ev = evs["gradient_chatter"][:500_000]
    print(f"\n## simulated emulation loop: {chunks} chunks of burn kernel + append of {len(ev) / 1e3:.0f} k "
          "gradient events (s, median)\n")
    _burn(10)
    _burn_nogil(10)
    write = median_time(lambda: write_stream(tmp / "c.h5", ev, False, "gradient_events", len(ev)), repeat)
    per = median_time(lambda: _burn(1_000_000), repeat)
    n = int(1_000_000 * write / per)
    print(f"writing one chunk in the foreground: {write * 1e3:.0f} ms; burn kernel calibrated to the same\n")
    print("| kernel | burn alone | foreground | background | background / foreground (min-max) | ideal |")
    print("|---|---|---|---|---|---|")
    for label, kernel in (("njit (holds the GIL)", _burn), ("njit(nogil=True)", _burn_nogil)):
        alone = median_time(lambda kernel=kernel: [kernel(n) for _ in range(chunks)], repeat)

        def one(bg: bool, kernel=kernel) -> float:
            tick = time.perf_counter()
            with EventWriter(tmp / f"b{int(bg)}.h5", background=bg, **META) as w:
                for k in range(chunks):
                    kernel(n)
                    piece = ev.copy()
                    piece["t"] += k * 10_000
                    w.append("gradient_events", piece)
            return time.perf_counter() - tick

        fg, bg, r = paired(one, repeat)
        # two stages in a pipeline: the longer one, plus one step of the shorter (the first burn, the last write)
        ideal = (max(alone, chunks * write) + min(alone / chunks, write)) / (alone + chunks * write)
        print(f"| {label} | {alone:.2f} | {fg:.2f} | {bg:.2f} | {ratio_cell(r)} | {ideal:.2f} |", flush=True)


def emulate(path: Path, background: bool, chunks: int) -> tuple[float, int]:
    run = FlickerRun()
    run.chunk(0)  # compiled already; the first chunk sets the memorised levels
    tick = time.perf_counter()
    n = 0
    with EventWriter(path, background=background, **META) as w:
        for k in range(1, chunks + 1):
            d, g = run.chunk(k)
            w.append("events", d)
            w.append("gradient_events", g)
            n += len(d) + len(g)
    return time.perf_counter() - tick, n


def section_emulation(tmp: Path, repeat: int, chunks: int, thread_counts: list[int]) -> None:
    print(f"\n## emulation loop: photoreceptor + DVS + gradient, {chunks} chunks of 200 steps, both streams "
          "appended (s, median)\n")
    print("| numba threads | events | no writes | foreground | background | background / foreground (min-max) |")
    print("|---|---|---|---|---|---|")
    for threads in thread_counts:
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        bare: list[float] = []
        counts = []

        def one(bg: bool) -> float:
            if bg:  # once a pair: the loop without writes
                run = FlickerRun()
                run.chunk(0)
                tick = time.perf_counter()
                for k in range(1, chunks + 1):
                    run.chunk(k)
                bare.append(time.perf_counter() - tick)
            s, n = emulate(tmp / f"e{int(bg)}.h5", bg, chunks)
            counts.append(n)
            return s

        fg, bg, r = paired(one, repeat)
        with EventReader(tmp / "e0.h5") as r0, EventReader(tmp / "e1.h5") as r1:
            for stream in ("events", "gradient_events"):
                assert np.array_equal(r0.read(stream), r1.read(stream))
        print(f"| {threads} | {counts[0] / 1e6:.1f} M | {float(np.median(bare)):.2f} | {fg:.2f} | {bg:.2f} | "
              f"{ratio_cell(r)} |", flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--chunks", type=int, default=10)
    ap.add_argument("--sections", default="bytes,writer,burn,emulation")
    ap.add_argument("--threads", default="1,2", help="numba thread counts of the emulation section")
    args = ap.parse_args()
    sections = args.sections.split(",")
    print(f"{os.cpu_count()} cores, h5py {h5py.version.version} (HDF5 {h5py.version.hdf5_version}), "
          f"numba {numba.__version__}, median of {args.repeat}")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        evs = streams() if {"bytes", "writer", "burn"} & set(sections) else {}
        if evs:
            print("streams: " + ", ".join(f"{k} {len(v) / 1e6:.2f} M events" for k, v in evs.items()))
        if "bytes" in sections:
            section_bytes(evs, tmp, args.repeat)
        if "writer" in sections:
            section_writer(evs, tmp, args.repeat)
        if "burn" in sections:
            section_burn(evs, tmp, args.repeat, args.chunks)
        if "emulation" in sections:
            section_emulation(tmp, args.repeat, args.chunks, [int(x) for x in args.threads.split(",")])


if __name__ == "__main__":
    main()
