"""The emulation driver: scene -> irradiance -> optics -> pixel -> event emulators,
in time chunks, streaming events and ground-truth frames to an HDF5 file.

Photocurrent is linear in each light group's radiance, so each group's basis
image is turned into a photocurrent basis once (luminance x lens x cos^4 x
pixel area x fill factor x the group's spectral responsivity); the
photocurrent of a step is sum_k w_k C_k, with w_k the exact average of the
waveform over the step (held input for the photoreceptor).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import time
from collections.abc import Callable

import numpy as np

from gevsim import _portable as pm
from gevsim._validate import real
from gevsim.emulation import layout
from gevsim.emulation.bridging import CROSSING_RULES, bridging_for
from gevsim.emulation.config import EmulationConfig, check_consistency
from gevsim.emulation.emulators import (
    APS_READ_SEED,
    APS_SEED,
    EMULATORS,
    PHOTORECEPTOR_SEED,
    READOUT_SEED,
    SEED_SLOTS,
    make_emulator,
)
from gevsim.emulation.footprint import chip_window
from gevsim.emulation.photocurrent import Setup, photocurrent_at  # noqa: F401 (imported from here by callers)
from gevsim.emulation.start import (  # noqa: F401 (step_grid, refine, held_photocurrent: their home before #34)
    MAX_SETTLE_PERIOD_S,
    burn_in,
    burn_in_span_s,
    common_period_s,
    held_photocurrent,
    refine,
    settle,
    step_grid,
)
from gevsim.emulation.stepping import StageClock, stage_names, stream_chunks
from gevsim.emulation.summary import RunSummary
from gevsim.emulation.truth import write_frames
from gevsim.errors import ConfigError, suggest
from gevsim.events.readout import Readout, chip_share, log_readouts
from gevsim.illumination import from_spec, weights_at
from gevsim.io import EventWriter
from gevsim.optics import Pixel, cos4_map, group_photocurrent_factors, lamp_spectrum, luminance
from gevsim.optics.photometry import K_M_LM_PER_W
from gevsim.pixel import ApsSensor, Photoreceptor, load_preset
from gevsim.pixel.noise import dark_current_a
from gevsim.pixel.presets import with_overrides
from gevsim.render import MitsubaScene, load, override, render_basis
from gevsim.render.scene_config import resolved_config, scene_optics
from gevsim.resources import budget_chunk_steps, check_emulation

log = logging.getLogger(__name__)
#: ``progress(done, total)``, called as work completes.
Progress = Callable[[int, int], None]
DEFAULT_SPECTRUM = "D65"  # for light groups given as RGB radiance without a lamp spectrum


def prepare(config: EmulationConfig, *, cache_dir: str | os.PathLike | None = None,
            progress: Progress | None = None) -> Setup:
    """Render (or load) the basis, and build the photocurrent basis and the sensor. The
    counterfactual variants of a run share it (:func:`counterfactual`)."""
    manifest = override(load(config.scene), source=config.source or None, **config.render)
    duration = config.duration_s or manifest.duration_s
    manifest = override(manifest, duration_s=duration)
    check_consistency(config, duration_s=duration)
    check_emulation(config, width=manifest.render.width, height=manifest.render.height, duration_s=duration)
    for name in config.emulators:
        if EMULATORS[name].even_size and (manifest.render.width % 2 or manifest.render.height % 2):
            raise ConfigError(f"{name} (resolution compression) needs an even width and height, got "
                              f"{manifest.render.width}x{manifest.render.height}", source=config.source,
                              key="emulation.emulators")
    preset = load_preset(config.sensor)
    if config.sensor_overrides:
        preset = with_overrides(preset, config.sensor_overrides, source=config.source, where="sensor")
    if config.footprint == "chip":  # the pixels see what the chip's own pixels see
        manifest = chip_window(manifest, preset, source=config.source or None)
    if config.aps and preset.aps is None:
        raise ConfigError(f"sensor preset {preset.name!r} has no [aps] table", source=config.source,
                          key="emulation.aps")
    scene = MitsubaScene(manifest)
    smallest = min((*config.thresholds_ln, preset.events.threshold_on_ln, preset.events.threshold_off_ln))
    basis = render_basis(scene, cache_dir=cache_dir, progress=progress, smallest_threshold_ln=smallest)
    lens, _ = scene_optics(manifest)
    pixel = Pixel(pitch_m=preset.pixel_pitch_m, fill_factor=preset.fill_factor, qe=preset.qe)
    spectra = [lamp_spectrum(g.emission.spectrum or DEFAULT_SPECTRUM) for g in manifest.light_groups]
    factors = group_photocurrent_factors(spectra, pixel=pixel, lens=lens)
    r = manifest.render
    cos4 = cos4_map(r.width, r.height, fov_x_deg=manifest.fov_deg)
    names = manifest.group_names
    for group in set(config.group_scale) | set(config.group_waveform):
        if group not in names:
            raise ConfigError(f"scene {manifest.name!r} has no light group {group!r}{suggest(group, names)}",
                              source=config.source, key=f"light.groups.{group}")
    scale = config.light_scale * np.array([config.group_scale.get(g, 1.0) for g in names])
    per_group = (factors * scale)[None, :, None, None] * cos4[None, None]
    assert basis.noise is not None  # render_basis always draws the error sample
    current = (luminance(basis.images) * per_group).astype(np.float64)
    noise = (luminance(basis.noise) * per_group).astype(np.float64)
    waveforms = tuple(from_spec(config.group_waveform[g], source=config.source, key=f"light.groups.{g}.waveform")
                      if g in config.group_waveform else w for g, w in zip(names, basis.waveforms))
    # Photocurrent = Y E_factor 683 area R_k; illuminance on the chip = Y E_factor 683 (both x cos4 x scale).
    lux_per_a = lens.irradiance_factor * K_M_LM_PER_W / factors
    return Setup(manifest, preset, basis.times_s, current, waveforms, duration, scene.variant, current_noise=noise,
                 render_quality=basis.noise_summary(), chip_lux_per_a=lux_per_a, scene=scene)


def counterfactual(setup: Setup, *, flicker: bool = True, noise: bool = True) -> Setup:
    """The same setup with every waveform at its mean (``flicker=False``) and/or an ideal
    pixel (``noise=False``): DESIGN.md's counterfactual runs, without re-rendering."""
    waveforms = setup.waveforms if flicker else tuple(w.constant() for w in setup.waveforms)
    preset = setup.preset if noise else setup.preset.ideal()
    return dataclasses.replace(setup, waveforms=waveforms, preset=preset)


def render_noise_floor(setup: Setup, *, frequency_hz: float) -> Setup:
    """The flicker-free scene whose render noise is redrawn at ``frequency_hz``: the
    render-noise floor of a flicker figure (DESIGN.md, render quality).

    Every lamp is at its mean, but the image alternates (square wave, 50 % duty)
    between ``C + D / sqrt 2`` and ``C - D / sqrt 2``, where ``C`` is the rendered
    basis and ``D`` its error sample (half the difference of two independent half
    renders, with the variance of ``C``'s error). The two states differ by an
    error of variance 2 var(C): as two independent renders of the achieved
    quality would. Events of this run beyond those of the flicker-free run are
    what render noise alone causes when lamp flicker re-mixes the noisy images
    at its fundamental frequency; full decorrelation at every transition makes
    it an upper estimate of render noise's share.
    """
    if setup.current_noise is None:
        raise ValueError("render_noise_floor: this setup carries no render-noise sample")
    period = 1.0 / real(frequency_hz, "frequency_hz", low=0.0, low_open=True)
    a = from_spec({"type": "pwm", "frequency_hz": frequency_hz, "duty": 0.5})
    b = from_spec({"type": "pwm", "frequency_hz": frequency_hz, "duty": 0.5, "phase_s": 0.5 * period})
    k = setup.current_basis.shape[1]
    # Every waveform has mean 1, so "lamps at their mean" is the basis itself. A PWM at duty 0.5
    # has values 0 and 2 (mean 1), so each half of the alternation carries half the basis.
    half = 0.5 * setup.current_basis
    d = 0.5 * setup.current_noise / np.sqrt(2.0)
    basis = np.concatenate([half + d, half - d], axis=1)
    return dataclasses.replace(setup, current_basis=basis, waveforms=(a,) * k + (b,) * k, current_noise=None)


def check_frames_fit(config: EmulationConfig, out: str | os.PathLike, *, width: int, height: int,
                     duration_s: float) -> None:
    """Refuse, before any work, ground-truth frames that would not fit on the disk that ``out`` goes to
    (their size before compression: two float32 log images, depth and 2-channel flow a frame, and an APS
    frame with ``aps``)."""
    from gevsim.resources import fits_disk

    check_consistency(config, duration_s=duration_s)  # the time grid first (at most MAX_FRAMES frames)
    frames = len(config.time.frame_times_s(duration_s))
    fits_disk(frames * width * height * (2 * 4 + 3 * 4 + (2 if config.aps else 0)), out,
              what=f"{frames} ground-truth frames of {width}x{height} px (frame_rate_hz = {config.frame_rate_hz:g} "
                   f"over {duration_s:g} s)", source=config.source, key="emulation.frame_rate_hz")


def run(config: EmulationConfig, out: str | os.PathLike, *, cache_dir: str | os.PathLike | None = None,
        flicker: bool = True, noise: bool = True, progress: Progress | None = None,
        render_progress: Progress | None = None, setup: Setup | None = None,
        before_commit: Callable[[os.PathLike], object] | None = None) -> RunSummary:
    """Run an emulation and write ``out`` (HDF5). Returns its :class:`RunSummary` (counts, rates, timings).

    ``setup`` (from :func:`prepare` with the same config) skips loading the basis again.
    ``before_commit(tmp)`` gets the finished file under its temporary name before it replaces ``out``
    (:meth:`gevsim.io.EventWriter.close`): a failure there leaves an earlier ``out`` untouched.
    Chunks have ``config.chunk_steps`` steps, or as many as the memory budget allows
    (:func:`gevsim.resources.budget_chunk_steps`); they change no result.
    """
    start = time.perf_counter()
    clock = StageClock(stage_names(n for n in EMULATORS if n in config.emulators))
    if os.path.isdir(out):
        raise ConfigError("is a folder; the output is an .h5 file", source=str(out))
    if setup is None:
        manifest = override(load(config.scene), source=config.source or None, **config.render)
        check_frames_fit(config, out, width=manifest.render.width, height=manifest.render.height,
                         duration_s=config.duration_s or manifest.duration_s)
    setup = setup if setup is not None else prepare(config, cache_dir=cache_dir, progress=render_progress)
    # The time grid (sub-steps, steps split at lamp jumps) comes from the run with flicker and noise,
    # so that its counterfactuals step alike and draw the same noise at the same steps (paired runs).
    sub = substeps(config, setup)
    check_emulation(config, width=setup.manifest.render.width, height=setup.manifest.render.height,
                    duration_s=setup.duration_s, substeps=sub)
    chunk = budget_chunk_steps(config, width=setup.manifest.render.width, height=setup.manifest.render.height,
                               substeps=sub)
    log.info("chunks of %d steps (%s)", chunk, "chunk_steps" if config.chunk_steps else "the memory budget")
    grid_waveforms = setup.waveforms
    setup = counterfactual(setup, flicker=flicker, noise=noise)
    t = clock.lap("render", start)
    preset, m = setup.preset, setup.manifest
    h, w = m.render.height, m.render.width
    pr, start_state, emulators, readouts, aps, aps_rng, bridging = _chain(config, setup, grid_waveforms=grid_waveforms,
                                                                          sub=sub, chunk_steps=chunk)
    t = clock.lap("start", t)
    end_us = int(round(setup.duration_s * 1e6))

    n_steps = config.time.steps(setup.duration_s)
    frame_t = config.time.frame_times_s(setup.duration_s)
    counts = {EMULATORS[n].stream: 0 for n in emulators}
    dark = dark_current_a(preset.noise, preset.photoreceptor.temperature_k)
    # render_noise_json with sorted keys: a fresh render and a cache hit list them in other orders.
    extra = {"scene": m.name, "sensor": preset.name, "step_s": config.step_s, "duration_s": setup.duration_s,
             "flicker": flicker, "noise": noise, "variant": setup.variant.variant,
             "scene_toml": resolved_config(m), "emulators": list(emulators),
             "render_noise_json": json.dumps(setup.render_quality, default=float, sort_keys=True),
             "start": start_state, "substeps": sub, "crossings": config.crossings}
    with EventWriter(out, width=w, height=h, config_toml=config.text or config.to_toml(), seed=config.seed,
                     extra_attrs=extra) as wr:
        for name, em in emulators.items():  # what reconstruction needs: theta, nominal contrast steps
            stored = EMULATORS[name].thresholds
            if stored is not None:
                layout.write_thresholds(wr, name, stored(em, preset))
        t = clock.lap("hdf5", t)
        if config.frame_rate_hz > 0:
            write_frames(wr, setup, frame_t, dark, aps, aps_rng, config)
        t = clock.lap("ground_truth", t)
        t = stream_chunks(config, setup, wr, pr, emulators, readouts, grid_waveforms=grid_waveforms, sub=sub,
                          chunk_steps=chunk, end_us=end_us, counts=counts, clock=clock, since=t, progress=progress,
                          bridging=bridging)
        readout = {EMULATORS[n].stream: r.summary() for n, r in readouts.items()}
        log_readouts(readout)
        t = clock.lap("readout", t)
        wr.set_attrs("/", readout_json=json.dumps(readout, sort_keys=True, default=float))
        wr.close(t_end_us=end_us, before_commit=clock.timed("before_commit", before_commit) if before_commit else None)
    clock.lap("hdf5", t)
    stage = clock.seconds
    log.info("seconds by stage: %s", ", ".join(f"{k} {v:.3g}" for k, v in stage.items()))
    pixel_s = stage["mix"] + stage["photoreceptor"]
    return RunSummary(
        out=str(out), width=w, height=h, steps=n_steps, duration_s=setup.duration_s, frames=len(frame_t),
        counts=counts, rates_hz={k: v / setup.duration_s for k, v in counts.items()},
        render_s=stage["render"], pixel_s=pixel_s, event_s={n: stage[n] for n in emulators},
        render_noise=setup.render_quality, pixel_steps_per_s=n_steps * sub * h * w / max(pixel_s, 1e-12),
        total_s=time.perf_counter() - start, readout=readout, chunk_steps=chunk, stage_s=dict(stage),
    )


def _chain(config: EmulationConfig, setup: Setup, *, grid_waveforms: tuple, sub: int, chunk_steps: int) -> tuple:
    """The run's pixel chain, each part seeded by its slot of the run's seed sequence: the photoreceptor
    (settled unless a cold start), the emulators, their readouts (the sensor's bus share of the window),
    the APS sensor and its read-noise generator (or None), and the crossing rule's noise-free twin
    (:func:`~gevsim.emulation.bridging.bridging_for`, or None)."""
    preset, m = setup.preset, setup.manifest
    h, w = m.render.height, m.render.width
    seeds = np.random.SeedSequence(config.seed).spawn(SEED_SLOTS)
    period = common_period_s(grid_waveforms)  # the flicker run's: its counterfactuals burn in alike (paired)
    span = 0.0 if config.cold_start else burn_in_span_s(config.burn_in_s, period)
    pr = Photoreceptor((h, w), params=preset.photoreceptor, noise=preset.noise, t0_s=-span,
                       rng=np.random.default_rng(seeds[PHOTORECEPTOR_SEED]), cold_start=config.cold_start)
    start_state = "cold" if config.cold_start else settle(pr, setup, config.step_s, chunk_steps=chunk_steps)
    try:
        bridging = None if config.cold_start else bridging_for(config.crossings, pr)
    except ValueError as exc:
        raise ConfigError(str(exc), source=config.source, key="emulation.crossings") from None
    emulators = {name: make_emulator(name, (h, w), config=config, preset=preset,
                                     rng=np.random.default_rng(seeds[entry.seed_slot]))
                 for name, entry in EMULATORS.items() if name in config.emulators}
    if span > 0:
        burn_in(pr, emulators, setup, span_s=span, step_s=config.step_s, sub=sub, chunk_steps=chunk_steps,
                grid_waveforms=grid_waveforms, periodic=period is not None, bridging=bridging)
        start_state += f"; the chain burnt in for {span * 1e3:.6g} ms before t = 0 (events discarded)"
    readout_key = np.random.default_rng(seeds[READOUT_SEED]).integers(0, 2**62)
    bus = chip_share(preset.readout, emulated_px=h * w, chip_px=preset.width * preset.height)
    readouts = {name: Readout(bus, key=int(readout_key) + EMULATORS[name].seed_slot, shape=(h, w),
                              hold_s=preset.events.refractory_s if EMULATORS[name].kind != "gradient" else 0.0)
                for name in emulators}  # each stream: the sensor's own bus; a pixel held in reset after its acknowledge
    aps = (ApsSensor((h, w), preset.aps, rng=np.random.default_rng(seeds[APS_SEED]))
           if config.aps and preset.aps is not None else None)  # prepare() refused aps without [aps]
    aps_rng = np.random.default_rng(seeds[APS_READ_SEED]) if config.aps else None
    return pr, start_state, emulators, readouts, aps, aps_rng, bridging


def substeps(config: EmulationConfig, setup: Setup) -> int:
    """How many equal sub-steps each configured step needs so that the sensor's fastest noise path
    is resolved (noise-event rates then do not depend on the step, within ~10 %), or, with a crossing rule
    that finds crossings between samples, so that no step is longer than the rule is validated at; 1 when
    the step is fine enough or the sensor sets no bound."""
    from gevsim.pixel.noise import coarsest_step_s

    t = np.linspace(0.0, setup.duration_s, 2001)
    peak = np.max(weights_at(setup.waveforms, t), axis=0)  # each group's brightest moment
    basis = setup.current_basis.max(axis=0)  # (K, H, W): each group's brightest pose
    brightest = float(np.max(pm.weighted_sum(peak[None, :], basis.reshape(len(basis), -1))))
    limit = CROSSING_RULES[config.crossings]
    why = f"crossings = {config.crossings!r} is validated to"
    if limit is None:
        limit = coarsest_step_s(setup.preset.photoreceptor, setup.preset.noise, brightest)
        why = f"the {setup.preset.name} pixel's fastest noise path allows"
    if limit is None or config.step_s <= limit * (1 + 1e-9):
        return 1
    k = int(np.ceil(config.step_s / limit - 1e-9))
    log.info("step_s = %g s is coarser than %s (%.3g s): %d sub-steps per step", config.step_s, why, limit, k)
    return k
