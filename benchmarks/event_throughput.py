"""Event throughput where flicker lives: events/s and pixel-steps/s per stage, side by side with v2e.

One command measures gevsim and, when it is importable, v2e's ``EventEmulator`` (Hu, Liu &
Delbruck 2021; github.com/SensorsINI/v2e, not on PyPI) on the same input, alternating chunk by
chunk. v2e is never a dependency of gevsim: it lives in a scratch environment that also holds
gevsim's runtime dependencies (numpy 2.4, numba 0.68 in both), and the benchmark runs there, from
the repository root (v2e's source checked out in /tmp/v2e_src)::

    /tmp/v2eenv/bin/pip install "mitsuba==3.9.1" "drjit==1.5.0" "OpenEXR==3.5.3" \\
        "colour-science==0.4.7" "tomli_w==1.2.0"          # gevsim's deps beside v2e's (once)
    PYTHONPATH=.:/tmp/v2e_src DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so \\
        /tmp/v2eenv/bin/python benchmarks/event_throughput.py [--sizes 346x260,1280x720] [--threads 1,2] \\
        [--repeat 3] [--steps 50] [--inputs flicker_pan,noisy_lowlight,sparse,office] \\
        [--cache /tmp/gevsim-bench-cache] [--office-spp 8] [--json OUT] [--quick]

Without v2e (``import v2ecore`` fails) the v2e rows and ratios are left out and the run says so.
On a machine shared with other work, add ``OMP_WAIT_POLICY=PASSIVE`` to the environment: torch and
numba (its ``omp`` layer) spin in OpenMP barriers, and with a core taken by another process v2e at 2
threads ran 25-50x slower (flicker_pan, 346x260: 6-23 s per 50-frame chunk instead of 0.27 s
passive; 1 thread 0.22 s either way). The header prints the setting; each input prints the load
average before and after it.
``--quick`` is a smoke run (64x48, 20 steps, 1 repeat, office at 2 spp).

Inputs (each a photocurrent sequence, float32 (T, H, W), processed in chunks of ``--steps`` steps):

- ``flicker_pan``: a scikit-image texture (``brick``) panning 1 px per step under a 100 Hz
  square-wave lamp (+-25 %), sampled at 2 kHz (500 us steps), noise-free pixel: about half
  a DVS event per pixel per step, the issue 13 case.
- ``noisy_lowlight``: the ``camera`` photograph at ~1 lux on the chip, davis346 noise on, 10 us
  steps: the gradient comparators chatter on pixel noise.
- ``sparse``: the ``camera`` photograph at ~1 klux with a 100 Hz 50 % sinusoid, 10 us steps
  (the sparse input of events_speed.py), davis346.
- ``office``: gevsim's built-in ``office`` scene (500 Hz PWM ceiling panel at 30 % duty and a
  daylight window), rendered at the benchmark's size with ``--office-spp`` samples per pixel
  (enough for events; this is about throughput, not render convergence; the basis is cached
  under ``--cache``), its photocurrent from the driver's ``weights_at``/``photocurrent_at``
  (step averages of the waveforms), 10 us steps, davis346.

Rows, per input, size and thread count (median, min, max over ``--repeat`` chunks after one
warm-up chunk; pixel-steps/s = T H W / seconds; events/s = events of the stage / its seconds):

- gevsim stages on the input's own sensor (noise-free for ``flicker_pan``, davis346 otherwise):
  ``photoreceptor``; ``DVS``, ``gradient``, ``CSDVS`` on its output; the paths
  ``pixel + DVS`` and ``pixel + DVS + gradient`` (sums of their stages' times on the same chunk).
- the issue's comparisons with v2e (ratio gevsim/v2e of pixel-steps/s, i.e. v2e's seconds over
  gevsim's on the same chunk, min / median / max over the repeats; and the event-count ratio):

  * ``DVS noise-free vs v2e noise-free``: both get the SAME float32 log frames,
    ``L = ln(max(DN, 0.1))`` with ``DN = 255 I / I_white`` (I_white: the input's brightest
    photocurrent in its first chunk). v2e takes them as log input (``hdr=True``: no lin-log,
    ``cutoff_hz=0``, no noise, no leak, ``sigma_thres=0``); gevsim's ``BrightnessEmulator``
    with ``EventParams()`` (0.2 / 0.2, no mismatch, no refractory period) takes them as its
    voltages. Computing L is outside both timings. The event counts must agree (count ratio ~1).
  * ``CSDVS vs v2e noise-free DVS``: gevsim's ``CenterSurroundEmulator`` on the same L.
  * ``CSDVS vs v2e CSDVS``: the same against v2e's own centre-surround DVS on L (``V2E_CSDVS``:
    2 px, surround time constant 1 ms, as gevsim's defaults).
  * ``pixel + noise + DVS vs v2e noisy``: gevsim's davis346 photoreceptor (shot, read, dark
    noise, mismatch, leak) + DVS on the photocurrent vs v2e on the linear frames DN with
    ``cutoff_hz=300``, ``shot_noise_rate_hz=5``, ``leak_rate_hz=0.1``, ``sigma_thres=0.03``
    (v2e's "noisy" model with a 300 Hz cutoff). The models differ, so the counts do too.
  * ``pixel + noise + DVS + gradient vs v2e noisy DVS alone``: the same plus gevsim's gradient
    events, against the same v2e run.

v2e runs on the CPU (``device="cpu"``) with ``torch.set_num_threads(n)`` for the row's n threads;
gevsim with ``numba.set_num_threads(n)`` (numba's pool is started with the machine's cores). Each
step is one v2e frame (``generate_events(frame, t)``). Per input and size (first thread count
only) it also writes the DVS and gradient events of one chunk with ``gevsim.io.EventWriter`` to a
temporary file and reports bytes per event (file size / events, streams of >= 10000 events) and
the write speed (one thread, compression included). Not a timed test.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from skimage import data
from skimage.transform import resize

from gevsim.events import BrightnessEmulator, CenterSurroundEmulator, GradientEmulator
from gevsim.io import EventWriter
from gevsim.pixel import EventParams, Photoreceptor, SensorPreset, load_preset

try:  # optional, from a scratch environment (see the docstring)
    import torch
    from v2ecore.emulator import EventEmulator
    V2E_MISSING = ""
except ImportError as exc:
    torch = EventEmulator = None
    V2E_MISSING = f"{type(exc).__name__}: {exc}"

MIN_STORED = 10_000  # events of a stream below which bytes per event are not reported
DN_FLOOR = 0.1  # DN: the log frames of the noise-free comparison are ln(max(DN, DN_FLOOR))
V2E_NOISY = {"sigma_thres": 0.03, "cutoff_hz": 300.0, "leak_rate_hz": 0.1, "shot_noise_rate_hz": 5.0}
#: v2e's centre-surround DVS with gevsim's defaults: space constant 2 px, surround time constant
#: tau_h = cs_tau_p_ms / lambda^2 = 1 ms (v2e steps its diffuser with Euler steps of tau / 5).
V2E_CSDVS = {"cs_lambda_pixels": 2.0, "cs_tau_p_ms": 4.0}
COMPARISONS = (  # (row, gevsim label, v2e label, counts should agree)
    ("DVS noise-free vs v2e noise-free", "DVS on ln frames", "v2e noise-free", True),
    ("CSDVS vs v2e noise-free DVS", "CSDVS on ln frames", "v2e noise-free", False),
    ("CSDVS vs v2e CSDVS", "CSDVS on ln frames", "v2e CSDVS", False),
    ("pixel + noise + DVS vs v2e noisy", "davis346 pixel + DVS", "v2e noisy", False),
    ("pixel + noise + DVS + gradient vs v2e noisy DVS", "davis346 pixel + DVS + gradient", "v2e noisy", False),
)


@dataclass
class Input:
    name: str
    preset: SensorPreset  # of the gevsim stage rows
    chunk: Callable[[int], tuple[np.ndarray, np.ndarray]]  # k -> (photocurrent (T, H, W) float32 A, t_end (T,) s)


@dataclass
class Chunk:
    current: np.ndarray  # (T, H, W) float32, A
    t: np.ndarray  # (T,) step end times, s
    dn: np.ndarray  # (T, H, W) float32: 255 I / I_white, v2e's linear frames
    ln: np.ndarray  # (T, H, W) float32: ln(max(dn, DN_FLOOR)), the shared log frames


def office_input(h: int, w: int, steps: int, preset: SensorPreset, *, cache: str, spp: int) -> Input:
    from gevsim.emulation.config import EmulationConfig
    from gevsim.emulation.driver import photocurrent_at, prepare
    from gevsim.illumination import weights_at

    setup = prepare(EmulationConfig(scene="office", render={"width": w, "height": h, "spp": spp}), cache_dir=cache)
    dt = 1e-5

    def office(k):
        t = dt * np.arange(k * steps + 1, (k + 1) * steps + 1)
        weights = weights_at(setup.waveforms, t - dt, average_over_s=dt)
        return photocurrent_at(setup, t - 0.5 * dt, weights).astype(np.float32), t

    return Input("office", preset, office)


def inputs(names: list[str], h: int, w: int, steps: int, ideal: SensorPreset, noisy: SensorPreset, *,
           chunks: int, cache: str, office_spp: int) -> list[Input]:
    i_ref = noisy.photoreceptor.cutoff_ref_photocurrent_a  # ~1 klux on the chip
    # Wide enough that the pan never wraps: a pixel that sees exactly the same values again can sit
    # exactly on a threshold, where rounding decides (gevsim moves its level to the crossing, v2e adds
    # n thresholds to its level) and the event counts part by ~0.4 %.
    brick = resize(data.brick().astype(float) / 255, (h, max(2 * w, w + steps * chunks))) * 0.9 + 0.05
    camera = resize(data.camera().astype(float) / 255, (h, w)) * 0.9 + 0.05

    def pan(k):
        dt = 5e-4
        n = np.arange(k * steps, (k + 1) * steps)
        t = dt * (n + 1)
        lamp = np.where(np.mod(t * 100.0, 1.0) < 0.5, 1.25, 0.75)  # 100 Hz square wave, +-25 %
        frames = np.stack([np.roll(brick, -int(j), axis=1)[:, :w] for j in n]) * lamp[:, None, None]
        return (i_ref * frames).astype(np.float32), t

    def lowlight(k):
        dt = 1e-5
        t = dt * np.arange(k * steps + 1, (k + 1) * steps + 1)
        return np.ascontiguousarray(np.broadcast_to((1e-3 * i_ref * camera).astype(np.float32), (steps, h, w))), t

    def sparse(k):
        dt = 1e-5
        t = dt * np.arange(k * steps + 1, (k + 1) * steps + 1)
        mod = (1 + 0.5 * np.sin(2 * np.pi * 100 * t)).astype(np.float32)
        return (i_ref * camera).astype(np.float32)[None] * mod[:, None, None], t

    made = {"flicker_pan": lambda: Input("flicker_pan", ideal, pan),
            "noisy_lowlight": lambda: Input("noisy_lowlight", noisy, lowlight),
            "sparse": lambda: Input("sparse", noisy, sparse),
            "office": lambda: office_input(h, w, steps, noisy, cache=cache, spp=office_spp)}
    unknown = [n for n in names if n not in made]
    if unknown:
        raise SystemExit(f"unknown input(s) {unknown}; choose from {list(made)}")
    return [made[n]() for n in names]


def timed(fn, *args):
    tick = time.perf_counter()
    out = fn(*args)
    return time.perf_counter() - tick, out


class GevsimStages:
    """Photoreceptor, then DVS, gradient (and CSDVS) on its output; the paths are sums of stage times."""

    def __init__(self, shape, preset: SensorPreset, *, seed: int, prefix: str = "", csdvs: bool = True):
        rng = np.random.default_rng(seed)
        self.prefix = prefix
        self.pr = Photoreceptor(shape, params=preset.photoreceptor, noise=preset.noise, rng=rng)
        self.dvs = BrightnessEmulator(shape, preset.events, rng=rng)
        self.grad = GradientEmulator(shape, mismatch_sigma_ln=preset.events.threshold_mismatch_ln, rng=rng)
        self.cs = CenterSurroundEmulator(shape, preset.events, rng=rng) if csdvs else None
        self.last: dict[str, np.ndarray] = {}

    def run(self, c: Chunk) -> dict[str, tuple[float, int]]:
        s_pr, v = timed(self.pr.process, c.current, c.t)
        s_dvs, ev = timed(self.dvs.process, v, c.t)
        s_grad, gev = timed(self.grad.process, v, c.t)
        self.last = {"events": ev, "gradient_events": gev}
        p = self.prefix
        rows = {f"{p}pixel + DVS": (s_pr + s_dvs, len(ev)),
                f"{p}pixel + DVS + gradient": (s_pr + s_dvs + s_grad, len(ev) + len(gev))}
        if self.cs is not None:
            s_cs, cev = timed(self.cs.process, v, c.t)
            rows = {"photoreceptor": (s_pr, 0), "DVS": (s_dvs, len(ev)), "gradient": (s_grad, len(gev)),
                    "CSDVS": (s_cs, len(cev)), **rows}
        return rows


class GevsimLog:
    """DVS and CSDVS (noise-free, EventParams()) on the shared log frames."""

    def __init__(self, shape, *, seed: int):
        rng = np.random.default_rng(seed)
        self.dvs = BrightnessEmulator(shape, EventParams(), rng=rng)
        self.cs = CenterSurroundEmulator(shape, EventParams(), rng=rng)

    def run(self, c: Chunk) -> dict[str, tuple[float, int]]:
        s_dvs, ev = timed(self.dvs.process, c.ln, c.t)
        s_cs, cev = timed(self.cs.process, c.ln, c.t)
        return {"DVS on ln frames": (s_dvs, len(ev)), "CSDVS on ln frames": (s_cs, len(cev))}


class V2e:
    """v2e's EventEmulator, one frame per step: noise-free on the log frames, or noisy on DN."""

    def __init__(self, *, noisy: bool, seed: int, csdvs: bool = False):
        assert torch is not None and EventEmulator is not None
        torch.manual_seed(seed)
        kw = (dict(V2E_NOISY) if noisy else
              {"sigma_thres": 0.0, "cutoff_hz": 0.0, "leak_rate_hz": 0.0, "shot_noise_rate_hz": 0.0, "hdr": True})
        if csdvs:
            kw.update(V2E_CSDVS)
        self.em = EventEmulator(pos_thres=0.2, neg_thres=0.2, device="cpu", output_folder=None, seed=seed, **kw)
        self.noisy = noisy
        self.label = "v2e CSDVS" if csdvs else "v2e noisy" if noisy else "v2e noise-free"

    def run(self, c: Chunk) -> dict[str, tuple[float, int]]:
        frames = c.dn if self.noisy else c.ln
        n = 0
        tick = time.perf_counter()
        for f, t in zip(frames, c.t):
            ev = self.em.generate_events(f, float(t))
            n += 0 if ev is None else len(ev)
        return {self.label: (time.perf_counter() - tick, n)}


def bytes_per_event(streams: dict[str, np.ndarray], h: int, w: int) -> dict[str, dict]:
    """Write each stream alone with EventWriter (its default compression) to a temporary file;
    streams of fewer than MIN_STORED events are left out (the file's fixed overhead would dominate)."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, ev in streams.items():
            if len(ev) < MIN_STORED:
                continue
            path = Path(tmp) / f"{name}.h5"
            tick = time.perf_counter()
            with EventWriter(path, width=w, height=h, config_toml="", seed=0) as wr:
                wr.append(name, ev)
                wr.close()
            s = time.perf_counter() - tick
            out[name] = {"events": len(ev), "bytes": path.stat().st_size,
                         "bytes_per_event": path.stat().st_size / len(ev), "write_events_per_s": len(ev) / s}
    return out


def spread(values) -> tuple[float, float, float]:
    return float(min(values)), float(statistics.median(values)), float(max(values))


def measure(inp: Input, h: int, w: int, steps: int, repeat: int, noisy: SensorPreset, *, v2e: bool,
            storage: bool) -> dict:
    shape = (h, w)
    runners: list = [GevsimStages(shape, inp.preset, seed=0)]
    if v2e:
        runners.append(V2e(noisy=False, seed=0))
    runners.append(GevsimLog(shape, seed=1))
    if v2e:
        runners.append(V2e(noisy=True, seed=0))
        runners.append(V2e(noisy=False, seed=0, csdvs=True))
    if inp.preset is not noisy:  # the davis346 path of the comparison; else the stage runner gives it
        runners.append(GevsimStages(shape, noisy, seed=2, prefix="davis346 ", csdvs=False))
    white = None
    samples: dict[str, list[tuple[float, int]]] = {}
    # All chunks are made before any timing: the office's photocurrent comes from Dr.Jit, whose
    # worker threads stayed busy for some milliseconds after each chunk and took a core from the
    # 2-thread runs that followed (346x260: gevsim's stages at 2 threads no faster than at 1).
    chunks = []
    for k in range(repeat + 1):
        current, t = inp.chunk(k)
        white = white or float(current.max()) or 1.0
        dn = current * np.float32(255.0 / white)
        chunks.append(Chunk(current, t, dn, np.log(np.maximum(dn, np.float32(DN_FLOOR)))))
    for k, c in enumerate(chunks):  # chunk 0: compile, initialise v2e; not timed
        for r in runners:  # alternating gevsim and v2e on the same chunk
            for label, s in r.run(c).items():
                if k:
                    samples.setdefault(label, []).append(s)
    # The input's own sensor is davis346: its stage rows are the comparison's noisy paths.
    alias = {f"davis346 {p}": p for p in ("pixel + DVS", "pixel + DVS + gradient")} if inp.preset is noisy else {}
    px = steps * h * w
    rows = {}
    for label, ss in samples.items():
        secs = [s for s, _ in ss]
        n = float(np.mean([e for _, e in ss]))
        rows[label] = {"seconds": secs, "events": [e for _, e in ss],
                       "px_steps_per_s": [px / s for s in secs], "events_per_s": [e / s for s, e in ss],
                       "events_per_px_step": n / px}
    comparisons = {}
    if v2e:
        for row, g, v, same in COMPARISONS:
            g = alias.get(g, g)
            ratios = [sv / sg for (sg, _), (sv, _) in zip(samples[g], samples[v])]
            ng, nv = sum(e for _, e in samples[g]), sum(e for _, e in samples[v])
            comparisons[row] = {"gevsim": g, "v2e": v, "ratio_px_steps": ratios,
                                "count_ratio": ng / nv if nv else None, "counts_should_agree": same}
    out = {"input": inp.name, "width": w, "height": h, "steps": steps, "rows": rows, "comparisons": comparisons}
    if storage:
        out["storage"] = bytes_per_event(runners[0].last, h, w)
    return out


def print_result(res: dict) -> None:
    name = res["input"]
    for label, r in res["rows"].items():
        s = statistics.median(r["seconds"])
        lo, med, hi = spread(r["px_steps_per_s"])
        ev = statistics.median(r["events_per_s"])
        print(f"  {name:14s} {label:32s} {s:8.4f} s/chunk {med / 1e6:8.1f} M px-steps/s ({lo / 1e6:.1f}-"
              f"{hi / 1e6:.1f}) {ev / 1e6:8.2f} M events/s  {r['events_per_px_step']:.4f} ev/px-step", flush=True)
    for row, c in res["comparisons"].items():
        lo, med, hi = spread(c["ratio_px_steps"])
        cr = "-" if c["count_ratio"] is None else f"{c['count_ratio']:.6f}"
        note = "same input: should be 1" if c["counts_should_agree"] else "different models"
        print(f"  {name:14s} {row:47s} gevsim/v2e {lo:5.2f} / {med:5.2f} / {hi:5.2f} (min/median/max)  "
              f"events gevsim/v2e {cr} ({note})", flush=True)
    for stream, st in res.get("storage", {}).items():
        print(f"  {name:14s} HDF5 {stream:20s} {st['bytes_per_event']:6.2f} bytes/event ({st['events']} events, "
              f"written at {st['write_events_per_s'] / 1e6:.1f} M events/s)", flush=True)


def summary(results: list[dict]) -> None:
    """The issue's table: ratio gevsim/v2e (min / median / max) per comparison, input, threads and size."""
    sizes = list(dict.fromkeys(f"{r['width']}x{r['height']}" for r in results))
    keys = list(dict.fromkeys((r["input"], r["threads"]) for r in results))
    print("\n| input | threads | path | " + " | ".join(sizes) + " |")
    print("|---|---|---|" + "---|" * len(sizes))
    for inp, threads in keys:
        for row, *_ in COMPARISONS:
            cells = []
            for size in sizes:
                hit = [r for r in results if r["input"] == inp and r["threads"] == threads
                       and f"{r['width']}x{r['height']}" == size and row in r["comparisons"]]
                cells.append(" / ".join(f"{x:.2f}" for x in spread(hit[0]["comparisons"][row]["ratio_px_steps"]))
                             if hit else "")
            print(f"| {inp} | {threads} | {row} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default=None, help="WxH list (default 346x260,1280x720; --quick: 64x48)")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--steps", type=int, default=None, help="steps per chunk (default 50; --quick: 20)")
    ap.add_argument("--repeat", type=int, default=None, help="timed chunks (default 3; --quick: 1)")
    ap.add_argument("--inputs", default="flicker_pan,noisy_lowlight,sparse,office")
    ap.add_argument("--cache", default="/tmp/gevsim-bench-cache", help="render cache of the office scene")
    ap.add_argument("--office-spp", type=int, default=None, help="samples per pixel (default 8; --quick: 2)")
    ap.add_argument("--no-v2e", action="store_true", help="leave v2e out even when it is importable")
    ap.add_argument("--json", default=None, metavar="OUT", help="also save every sample as JSON")
    ap.add_argument("--quick", action="store_true", help="smoke run: 64x48, 20 steps, 1 repeat")
    args = ap.parse_args()
    sizes = args.sizes or ("64x48" if args.quick else "346x260,1280x720")
    steps = args.steps or (20 if args.quick else 50)
    repeat = args.repeat or (1 if args.quick else 3)
    spp = args.office_spp or (2 if args.quick else 8)
    v2e = EventEmulator is not None and not args.no_v2e
    if v2e:
        logging.getLogger("v2ecore").setLevel(logging.ERROR)  # "no signal events" etc. on every quiet frame
    ideal, noisy = load_preset("davis346").ideal(), load_preset("davis346")
    print(f"{os.cpu_count()} cores, numba {numba.__version__} ({numba.config.THREADING_LAYER} layer requested), "
          f"OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY', '(unset)')}, "
          f"chunks of {steps} steps, median of {repeat} (after a warm-up chunk)")
    if v2e:
        print(f"v2e: EventEmulator from {Path(EventEmulator.__module__.replace('.', '/')).parent} "
              f"(torch {torch.__version__}, device cpu, torch.set_num_threads(n) per row); noisy: {V2E_NOISY}")
    else:
        print(f"v2e rows skipped: {'--no-v2e' if args.no_v2e else 'import v2ecore failed (' + V2E_MISSING + ')'}")
    results = []
    for size in sizes.split(","):
        w, h = (int(x) for x in size.split("x"))
        cases = inputs(args.inputs.split(","), h, w, steps, ideal, noisy, chunks=repeat + 1, cache=args.cache,
                       office_spp=spp)
        for j, threads in enumerate(int(x) for x in args.threads.split(",")):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            if v2e:
                torch.set_num_threads(threads)
            print(f"{w}x{h}, {threads} thread(s)", flush=True)
            for inp in cases:
                before = os.getloadavg()[0]
                res = measure(inp, h, w, steps, repeat, noisy, v2e=v2e, storage=j == 0)
                res.update(threads=threads, load_before=before, load_after=os.getloadavg()[0])
                print_result(res)
                print(f"  {inp.name:14s} load average {before:.2f} before, {res['load_after']:.2f} after "
                      f"({os.cpu_count()} cores; other work on the machine skews both sides)", flush=True)
                results.append(res)
    print(f"numba threading layer used: {numba.threading_layer()}")
    if v2e:
        summary(results)
    if args.json:
        meta = {"cores": os.cpu_count(), "numba": numba.__version__, "numba_threading_layer": numba.threading_layer(),
                "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY"),
                "steps": steps, "repeat": repeat,
                "office_spp": spp, "v2e": v2e, "v2e_noisy": V2E_NOISY, "dn_floor": DN_FLOOR,
                "torch": torch.__version__ if v2e else None}
        Path(args.json).write_text(json.dumps({"meta": meta, "results": results}, indent=1))
        print(f"saved {args.json}")


if __name__ == "__main__":
    main()
