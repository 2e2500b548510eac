"""``gevsim emulate``: events from a scene config or from frames."""

from __future__ import annotations

import argparse
import sys

from gevsim.cli._common import _emulator_names, _progress, _render_overrides
from gevsim.errors import ConfigError


def _override_emulation(config, args: argparse.Namespace):
    """An emulation config with the command line's --width/--height/--duration/--emulators/--cold-start."""
    import dataclasses

    changes: dict = {}
    if _render_overrides(args):
        changes["render"] = {**config.render, **_render_overrides(args)}
    if args.duration is not None:
        changes["duration_s"] = args.duration
    if (names := _emulator_names(args)) is not None:
        changes["emulators"] = names
    if getattr(args, "cold_start", False):
        changes["cold_start"] = True
    if not changes:
        return config
    config = dataclasses.replace(config, **changes)
    return dataclasses.replace(config, text=config.to_toml())


def cmd_emulate(args: argparse.Namespace) -> int:
    from pathlib import Path

    if sum(x is not None for x in (args.config, args.frames, args.evreal, args.video)) != 1:
        raise ConfigError("give exactly one of CONFIG.toml, --frames DIR, --evreal DIR or --video FILE")
    if Path(args.out).suffix not in (".h5", ".hdf5"):
        raise ConfigError(f"--out must name an .h5 file, got {args.out!r}", key="--out")
    if Path(args.out).is_dir():
        raise ConfigError(f"{args.out} is a folder; name an .h5 file", key="--out")
    from gevsim.io.ownership import check_file, is_event_file, sweep_beside

    # Only an earlier emulation file is replaced, never an input of this run.
    check_file(args.out, "emulation", is_event_file, inputs=[args.config, args.frames, args.evreal, args.video])
    from gevsim.resources import check_writable

    check_writable(args.out)  # before the render: a read-only or missing place fails now
    sweep_beside(args.out)
    if args.config is None:
        return _emulate_frames(args)
    if args.log is not None:
        raise ConfigError("--log sets how frame mode takes the log of frames; a scene's pixel model has its own",
                          key="--log")
    from gevsim.emulation import load_config, run
    from gevsim.emulation import summary as summary_mod

    config = _override_emulation(load_config(args.config), args)
    update, close = _progress("emulate", not args.quiet, unit="chunk")
    render_update, render_close = _progress("render", not args.quiet)
    stats = {}
    try:  # the statistics are read back before the file replaces an earlier one: a failure there keeps it
        summary = run(config, args.out, cache_dir=args.cache, flicker=not args.no_flicker, noise=not args.no_noise,
                      progress=update, render_progress=render_update,
                      before_commit=lambda tmp: stats.update(summary_mod.summarize(tmp)))
    finally:
        render_close()
        close()
    print(f"gevsim: {summary.width}x{summary.height}, {summary.steps} steps of "
          f"{config.step_s * 1e6:g} us ({summary.duration_s * 1e3:g} ms), {summary.frames} ground-truth frames;"
          f" pixel model {summary.pixel_steps_per_s / 1e6:.1f} M pixel-steps/s", file=sys.stderr)
    print(f"{'stream':20s} {'made':>10s} {'delivered':>10s} {'lost':>10s} {'events/s':>11s} {'per pixel/s':>11s} "
          f"{'p/frame':>8s} {'emulator s':>10s}  (made: the pixels' crossings; delivered: what the bus carried)")
    for (name, count), seconds in zip(summary.counts.items(), summary.event_s.values()):
        st = stats[name]
        p_frame = f"{st.event_probability:8.3f}" if config.frame_rate_hz > 0 else f"{'-':>8s}"  # no frames: none
        made, lost, note = bus_columns(summary.readout.get(name, {}), count, pixels=summary.width * summary.height,
                                       duration_s=summary.duration_s)
        print(f"{name:20s} {made:10d} {count:10d} {lost:10d} {st.rates_hz['total']:11.4g} "
              f"{st.rates_hz['per_pixel_hz']:11.4g} {p_frame} {seconds:10.2f}{note}")
    print(f"gevsim: wrote {args.out} in {summary.total_s:.1f} s", file=sys.stderr)
    return 0


def _check_sensor_flags(args: argparse.Namespace) -> None:
    """Frame mode through a sensor: its flags, checked before any frame is read."""
    from gevsim.emulation.frame_sensor import check_lux

    if args.sensor is None or args.illuminance_lux is None:
        raise ConfigError("frame mode through a sensor needs both --sensor NAME and --illuminance-lux LUX",
                          key="--sensor" if args.sensor is None else "--illuminance-lux")
    for flag, value in (("--threshold-mismatch", args.threshold_mismatch), ("--log", args.log)):
        if value is not None:
            raise ConfigError(f"{flag} belongs to the paper's frame mode; with --sensor the preset sets the pixel",
                              key=flag)
    check_lux(args.illuminance_lux)


def _frames_through_sensor(args: argparse.Namespace, frames, t_s, source) -> int:
    """Frame mode through the physical pixel (:mod:`gevsim.emulation.frame_sensor`): the frames' span rounded
    down to whole steps, ground-truth frames at 1 kHz (fewer over clips longer than 1000 s: at most MAX_FRAMES)."""
    from gevsim.emulation import EmulationConfig, run
    from gevsim.emulation.frame_sensor import frame_setup
    from gevsim.pixel import load_preset
    from gevsim.timebase import MAX_FRAMES

    setup = frame_setup(frames, t_s, preset=load_preset(args.sensor), illuminance_lux=args.illuminance_lux,
                        source=source, step_s=EmulationConfig.step_s)
    names = _emulator_names(args)
    config = EmulationConfig(scene=str(source), sensor=args.sensor, seed=args.seed or 0, duration_s=setup.duration_s,
                             emulators=tuple(names) if names else EmulationConfig.emulators,
                             frame_rate_hz=min(EmulationConfig.frame_rate_hz, (MAX_FRAMES - 2) / setup.duration_s))
    summary = run(config, args.out, setup=setup, noise=not args.no_noise)
    print(f"{'stream':22s} {'events':>10s} {'events/s':>12s}")
    for name, count in summary.counts.items():
        print(f"{name:22s} {count:10d} {count / summary.duration_s:12.4g}")
    span = float(t_s[-1] - t_s[0])
    cut = "" if setup.duration_s == span else f" (the frames span {span:.9g} s: rounded down to whole steps)"
    print(f"gevsim: {len(frames)} frames {summary.width}x{summary.height} from {source} through {args.sensor} at "
          f"{args.illuminance_lux:g} lx, {summary.steps} steps of {config.step_s * 1e6:g} us = "
          f"{summary.duration_s:.9g} s{cut}; wrote {args.out}", file=sys.stderr)
    return 0


def _emulate_frames(args: argparse.Namespace) -> int:
    from gevsim.emulation import run_frames
    from gevsim.io import frames as loaders

    given = [flag for flag, value in (("--width", args.width), ("--height", args.height),
                                      ("--duration", args.duration)) if value is not None]
    if given:
        raise ConfigError(f"frame mode takes its size and times from the frames; drop {', '.join(given)}",
                          key=given[0])
    through_sensor = args.sensor is not None or args.illuminance_lux is not None
    if through_sensor:
        _check_sensor_flags(args)
    elif args.seed is not None and args.threshold_mismatch is None:
        raise ConfigError("--seed draws the DVS threshold mismatch: give --threshold-mismatch LN as well",
                          key="--seed")
    if args.evreal is not None:
        frames, t_s = loaders.load_evreal_frames(args.evreal)
        source = args.evreal
    elif args.video is not None:
        frames, t_s = loaders.load_video(args.video, fps=args.fps)
        source = args.video
    else:
        frames, t_s = loaders.load_frame_folder(args.frames, fps=args.fps)
        source = args.frames
    if through_sensor:
        return _frames_through_sensor(args, frames, t_s, source)
    from gevsim.emulation.emulators import FRAME_EMULATORS

    names = _emulator_names(args, FRAME_EMULATORS)
    summary = run_frames(frames, t_s, args.out, seed=args.seed or 0, source=source,
                         emulators=names or FRAME_EMULATORS, threshold_mismatch_ln=args.threshold_mismatch or 0.0,
                         log_mode=args.log or "offset")
    print(f"{'stream':22s} {'events':>10s} {'events/s':>12s}")
    for name, count in summary["counts"].items():
        print(f"{name:22s} {count:10d} {count / summary['duration_s']:12.4g}")
    print(f"gevsim: {summary['frames']} frames {summary['width']}x{summary['height']} from {source}; "
          f"wrote {args.out}", file=sys.stderr)
    return 0


#: A stream whose delivered rate is within this share of its bus's cap is at the cap: its count says what the
#: bus carried, not what the pixels made.
AT_CAP_SHARE = 0.98


def bus_columns(readout: dict, delivered: int, *, pixels: int, duration_s: float) -> tuple[int, int, str]:
    """(made, lost, note) of a stream from its readout counts: the pixels' crossings, those the bus did not
    deliver (not sent by a waiting pixel, dropped, filtered, still waiting at the end), and "  at the bus cap
    (N ev/px/s)" where the delivered rate is the cap's."""
    made = int(readout.get("requested", delivered))
    cap = float(readout.get("max_rate_eps", float("inf")))
    at_cap = cap < float("inf") and delivered >= AT_CAP_SHARE * cap * duration_s
    note = f"  at the bus cap ({cap / pixels:.4g} ev/px/s)" if at_cap else ""
    return made, made - delivered, note

