"""One job of a study: repeat r of a run, with its counterfactuals (common random numbers).

Repeat r of a run uses the noise seed ``study seed + r`` for the run as is and for
each of its counterfactuals (DESIGN.md, Counterfactual runs): with every lamp at
its mean (``no_flicker``), with an ideal pixel as well (``ideal``), and the
render-noise floor (:func:`gevsim.emulation.driver.render_noise_floor`). Sharing
the seed pairs them: the pixel noise that the flicker does not change is drawn
alike in all of them, so their differences carry less noise than independent
runs would (common random numbers). Repeats differ only in the seed, so their
differences are independent draws of the same quantity, and their spread gives
the interval (:mod:`gevsim.experiments.aggregate`).

A job writes ``runs/<id>/r<k>.npz`` (per-pixel event counts, phase-folded event
histograms, the scene's mean photocurrent and dominant light group) and then
``runs/<id>/r<k>.json`` (counts, reconstruction scores), the marker that it is
finished, each atomically. Jobs share nothing but the render cache, so they run
in any order, in any process (:mod:`gevsim.experiments.executors`), and give the
same numbers.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

import gevsim
from gevsim._portable import weighted_sum
from gevsim.emulation.emulators import EMULATORS, HEADLINE
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.study import Study, flicker_group, run_config, run_id
from gevsim.experiments.variations import LIGHT_VARIANTS, is_sensitivity
from gevsim.io import atomic_path, atomic_write_text
from gevsim.metrics.attribution import PHASE_BINS, phase_histogram

#: The four emulations of a repeat: name -> keyword arguments of :func:`gevsim.emulation.run`.
VARIANTS: dict[str, dict[str, Any]] = {"run": {}, "no_flicker": {"flicker": False},
                                       "ideal": {"flicker": False, "noise": False},
                                       "render_floor": {"noise": False}}
#: Variants whose per-pixel counts and phase histograms are kept (flicker maps, phase-locked estimate).
FOLDED = ("run", "no_flicker")
#: Alternation frequency of the render-noise floor when the swept lamp is steady.
DEFAULT_FLOOR_HZ = 100.0
#: Time bin of the DVS event-rate spectrum (s).
SPECTRUM_BIN_S = 1e-4


def repeat_seed(study: Study, repeat: int) -> int:
    """Noise seed of repeat ``repeat``: the study's seed plus the repeat (repeat 0 is ``gevsim emulate``'s run)."""
    return int(study.base["seed"]) + int(repeat)


def repeat_paths(out: str | os.PathLike, rid: str, repeat: int) -> tuple[Path, Path, Path]:
    """(marker .json, arrays .npz, folder of its HDF5 files) of a repeat."""
    folder = Path(out) / "runs" / rid
    return folder / f"r{repeat}.json", folder / f"r{repeat}.npz", folder / f"r{repeat}"


def finished_repeat(out: str | os.PathLike, rid: str, repeat: int) -> dict | None:
    """The record of a finished repeat, or None."""
    marker, arrays, _ = repeat_paths(out, rid, repeat)
    try:
        record = json.loads(marker.read_text())
    except (OSError, ValueError):
        return None
    return record if arrays.is_file() and record.get("repeat") == repeat else None


def _rate_bins(duration_s: float, bin_s: float = SPECTRUM_BIN_S) -> int:
    return max(2, int(round(duration_s / bin_s)))


def event_spectrum(counts: np.ndarray, *, bin_s: float = SPECTRUM_BIN_S) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude spectrum of the event rate (events/s per Hz bin) from event counts in time bins of
    ``bin_s`` (:func:`_fold`'s ``rate``), for the harmonics plot."""
    rate = np.asarray(counts, float) / bin_s
    amp = np.abs(np.fft.rfft(rate - rate.mean())) / len(rate)
    return np.fft.rfftfreq(len(rate), bin_s), amp


def _fold(path: Path, stream: str, periods: dict[str, float], shape: tuple[int, int], duration_s: float) -> dict:
    """Per-pixel counts, per light group the phase histogram, and the counts in time bins of
    :data:`SPECTRUM_BIN_S` (``rate``) of a stream, read window by window."""
    from gevsim.io import EventReader

    h, w = shape
    per_pixel = np.zeros(h * w, np.int64)
    phases = {g: np.zeros(PHASE_BINS, np.int64) for g in periods}
    rate = np.zeros(_rate_bins(duration_s), np.int64)
    with EventReader(path) as r:
        for start, end in r.windows(stream, 0, int(r.t_end_us) + 1):  # bounded memory at any event rate
            ev = r.read(stream, start, end)
            per_pixel += np.bincount(ev["y"].astype(np.int64) * w + ev["x"], minlength=h * w)
            t_s = ev["t"] * 1e-6
            for g, period in periods.items():
                phases[g] = phases[g] + phase_histogram(t_s, period_s=period)
            rate += np.histogram(t_s, bins=rate.size, range=(0, duration_s))[0]
    return {"pixels": per_pixel.reshape(h, w), "phases": phases, "rate": rate}


def execute_repeat(study: Study, params: dict, repeat: int, out: str | os.PathLike, *,
                   cache_dir: str | os.PathLike | None = None, keep_files: bool = False,
                   threads: int | None = None, rid: str | None = None) -> dict:
    """Emulate repeat ``repeat`` of a run and its counterfactuals, score reconstructions, write the
    repeat's arrays and marker; return its record (picklable: what executors run).

    ``threads`` sets numba's threads for this job; 0 keeps the count the executor gave its worker
    (:func:`gevsim.experiments.executors.worker_threads`), None numba's default. ``rid`` is the run's
    :func:`run_id` when the caller has it (computing it hashes every file of the scene)."""
    from gevsim.emulation import prepare, run
    from gevsim.emulation.driver import render_noise_floor
    from gevsim.emulation.summary import summarize

    if threads is not None:  # in an executor's worker
        _in_worker(threads)
    start = time.perf_counter()
    rid = run_id(study, params) if rid is None else rid
    marker, arrays, folder = repeat_paths(out, rid, repeat)
    folder.mkdir(parents=True, exist_ok=True)
    cfg = run_config(study, params, seed=repeat_seed(study, repeat))
    setup = prepare(cfg, cache_dir=cache_dir)  # rendered once (cache), shared by the four variants
    m = setup.manifest
    h, w = m.render.height, m.render.width
    periods = {g: wf.period_s for g, wf in zip(m.group_names, setup.waveforms) if wf.period_s}
    # Fundamental of the swept group's light (its waveform as the run uses it; None for a steady lamp).
    group = flicker_group(study, params.get("scene", study.base["scene"]))
    frequency = 1.0 / periods[group] if group in periods else None
    counts: dict[str, dict[str, int]] = {}
    made: dict[str, dict[str, int]] = {}  # what the pixels made (the readout's requests), before the bus
    saturated: dict[str, list[str]] = {}
    folded: dict[str, dict[str, dict]] = {}
    light = is_sensitivity(params)  # rates only
    for name, kw in VARIANTS.items():
        if light and name not in LIGHT_VARIANTS:
            continue
        use = render_noise_floor(setup, frequency_hz=frequency or DEFAULT_FLOOR_HZ) if name == "render_floor" \
            else setup
        with _quiet_readout():  # the report says which runs the bus limited: not 4 warnings per repeat
            info = run(cfg, folder / f"{name}.h5", setup=use, **kw)
        counts[name] = dict(info.counts)
        made[name] = {stream: int(c["requested"]) for stream, c in info.readout.items()}
        saturated[name] = bus_limited(info.readout)
        if name == "run":
            stats, summary = summarize(folder / "run.h5"), info
            if repeat == 0 and not light:
                record_strip = event_strip(folder / "run.h5", Path(out) / "runs" / rid / STRIP_FILE,
                                           periods.get(group), summary.duration_s)
        if name in FOLDED:
            folded[name] = {e: _fold(folder / f"{name}.h5", EMULATORS[e].stream, periods, (h, w),
                                     summary.duration_s) for e in cfg.emulators}
    record: dict[str, Any] = {"id": rid, "repeat": repeat, "seed": cfg.seed, "params": params, "pixels": h * w,
              "width": w, "height": h, "duration_s": summary.duration_s, "steps": summary.steps,
              "flicker_frequency_hz": frequency, "periods_s": periods, "counts": counts, "made": made,
              "bus_limited": saturated,
              "event_probability": {e: stats[EMULATORS[e].stream].event_probability
                                    for e in cfg.emulators},
              "render": _render_quality(setup.render_quality), "metrics": {},
              "bus_cap_per_pixel_s": _bus_cap(info.readout, h * w)}
    if repeat == 0 and not light:
        record["strip"] = record_strip
    if not light:
        record["metrics"] = _scores(folder / "run.h5", study.base["methods"], aps=cfg.aps)
    baseline = HEADLINE[0]  # the spectrum of the stream the report compares against
    if baseline in cfg.emulators and repeat == 0:
        f, amp = event_spectrum(folded["run"][baseline]["rate"])
        record[f"{baseline}_spectrum"] = {"hz": f.tolist(), "amplitude": amp.tolist()}
    with atomic_path(arrays) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **_arrays(setup, folded))
    record.update(seconds=time.perf_counter() - start, gevsim=gevsim.__version__)
    atomic_write_text(marker, json.dumps(record, default=float))  # the marker: written last
    if not keep_files:
        shutil.rmtree(folder, ignore_errors=True)
    return record


def _in_worker(threads: int) -> None:
    """An executor's worker: numba's threads set (0: as the executor set them), the render's quality warnings
    held back (the parent rendered or loaded every basis before fanning out and logged them once)."""
    import logging

    if threads:
        import numba

        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    logging.getLogger("gevsim.render").setLevel(logging.ERROR)


def _bus_cap(readout: dict[str, dict], pixels: int) -> float | None:
    """The bus's cap in events per pixel per second for the emulated window (None: no cap)."""
    caps = [float(c["max_rate_eps"]) for c in readout.values() if "max_rate_eps" in c]
    return min(caps) / pixels if caps and min(caps) < float("inf") else None


def _scores(path: Path, methods: list[str], *, aps: bool) -> dict[str, dict[str, float]]:
    """Each method's mean MSE/SSIM/PSNR on the run's file against the flicker-free reference (NaN for a
    method that needs APS frames the sensor does not have)."""
    from gevsim.evaluation import reconstruct_file

    scores = {}
    for method in methods:
        if METHODS[method].needs_aps and not aps:  # the sensor has no APS: nothing to fuse
            scores[method] = {k: float("nan") for k in ("mse", "ssim", "psnr")}
            continue
        rec, _, _ = reconstruct_file(path, method, reference="no-flicker")
        scores[method] = {k: float(v) for k, v in rec.mean_metrics().items()}
    return scores


def _arrays(setup: Any, folded: dict[str, dict[str, dict]]) -> dict[str, Any]:
    """The repeat's maps (mean photocurrent, chip illuminance, dominant light group) and its folded events
    (per-pixel counts and phase histograms per variant and emulator): what ``r<k>.npz`` holds."""
    mean_basis = setup.current_basis.mean(axis=0)  # (K, H, W), A per unit waveform
    assert setup.chip_lux_per_a is not None  # prepare() sets it
    data: dict[str, Any] = {
            "mean_current_a": mean_basis.sum(axis=0),
            "chip_lux": weighted_sum(np.asarray(setup.chip_lux_per_a)[None, :], mean_basis.reshape(len(mean_basis), -1))
            .reshape(mean_basis.shape[1:]),
            "dominant_group": np.argmax(mean_basis, axis=0).astype(np.int16),
            "group_names": np.array(setup.manifest.group_names)}
    for variant, per_emulator in folded.items():
        for e, fold in per_emulator.items():
            data[f"pixels/{variant}/{e}"] = fold["pixels"].astype(np.int32)
            for g, hist in fold["phases"].items():
                data[f"phases/{variant}/{e}/{g}"] = hist
    return data


#: The picture of a run's events (repeat 0) beside its repeats: ``runs/<id>/events.png`` (``gevsim view``).
STRIP_FILE = "events.png"


def event_strip(run_file: Path, out: Path, period_s: float | None, duration_s: float) -> dict:
    """Draw the last flicker period of a run (``period_s``; the last 8 ms for a steady lamp; at most the
    whole run) as a
    :func:`gevsim.view.view` strip of ``STRIP_ROWS`` windows into ``out``; returns where it lies
    in time (``window_us``, ``start_us``), for the report's caption."""
    from gevsim.view import STRIP_ROWS, view

    span_us = round(min(period_s or 8e-3, duration_s) * 1e6)
    window_us = max(1, span_us // STRIP_ROWS)
    start_us = max(0, round(duration_s * 1e6) - STRIP_ROWS * window_us)
    view(run_file, out, window_us=window_us, start_us=start_us)
    return {"file": STRIP_FILE, "window_us": window_us, "start_us": start_us}


#: A stream is bus-limited when its readout lost more than this share of the requested events (dropped by
#: the arbiter or the rate controller, not sent because their pixel was waiting for its acknowledge, or still
#: waiting at the end): then its counts say what the bus delivered, not what the pixels made. (Short waits
#: change no counts: synchronous flicker bursts wait a while even where the mean rate fits the bus.)
BUS_LIMITED_SHARE = 0.01


@contextlib.contextmanager
def _quiet_readout() -> Iterator[None]:
    """The readout's per-run log lines held back (to ERROR) for the block, then restored."""
    import logging

    logger = logging.getLogger("gevsim.events.readout")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def bus_limited(readout: dict[str, dict]) -> list[str]:
    """The streams whose readout (a run's :attr:`~gevsim.emulation.summary.RunSummary.readout` counts) limited
    their counts (:data:`BUS_LIMITED_SHARE`)."""
    return sorted(stream for stream, c in readout.items()
                  if c["dropped"] + c["pending_at_end"] + c["rate_controller_dropped"] + c.get("unsent", 0)
                  > BUS_LIMITED_SHARE * c["requested"])


def _render_quality(quality: dict) -> dict:
    return {"spp_min": quality["spp_min"], "spp_max": quality["spp_max"], "se_ln": quality["se_ln"]["at_percentile"],
            "percentile": quality["percentile"], "target_ln": quality["target_ln"], "reached": quality["reached"]}
