"""Command line: ``gevsim info``, ``scenes``, ``render``, ``emulate``, ``reconstruct``, ``export``, ``study``,
``dataset``.

The CLI parses arguments, sets up logging and progress bars and calls the
library. Bad input (:class:`~gevsim.errors.ConfigError`) and a missing optional
extra (:class:`~gevsim.errors.MissingExtraError`) print one line naming the file
and key and exit with code 2; anything else is a bug and shows its traceback.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from collections.abc import Callable

from gevsim.errors import ConfigError, GevsimError

log = logging.getLogger("gevsim")


def _positive(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = float(text)
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value


def _non_negative(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = float(text)
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative number, got {text}")
    return value


def _progress(desc: str, enabled: bool, unit: str = "pose"):
    """A ``progress(done, total)`` callback drawing a tqdm bar (or nothing: with ``-q``, or when
    stderr is not a terminal, where a bar's redraws would fill a log file)."""
    if not enabled or not sys.stderr.isatty():
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(desc=desc, unit=unit, leave=True, dynamic_ncols=True)

    def update(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    return update, bar.close


def cmd_info(args: argparse.Namespace) -> int:
    from gevsim._lock import status
    from gevsim.render.backend import describe

    for key, value in {**describe(), "lock": status()}.items():
        print(f"{key:>9}: {value}")
    return 0


def cmd_presets(args: argparse.Namespace) -> int:
    from gevsim.pixel.presets import load_preset, preset_names

    print(f"{'preset':14s} {'size':>9s} {'pitch um':>8s} {'fill':>5s} {'ON/OFF ln':>11s} {'mismatch':>8s} "
          f"{'cutoff Hz':>9s} {'dark A':>9s} {'APS':>4s}  description")
    for name in preset_names():
        p = load_preset(name)
        e = p.events
        print(f"{name:14s} {f'{p.width}x{p.height}':>9s} {p.pixel_pitch_m * 1e6:8.2f} {p.fill_factor:5.2f} "
              f"{e.threshold_on_ln:5.3g}/{e.threshold_off_ln:<5.3g} {e.threshold_mismatch_ln:8.3g} "
              f"{p.photoreceptor.cutoff_hz:9.4g} {p.noise.dark_current_a:9.2g} {'yes' if p.aps else 'no':>4s}  "
              f"{p.description}")
    return 0


def cmd_scenes(args: argparse.Namespace) -> int:
    from gevsim.render import builtin_scenes, load

    for name, path in builtin_scenes().items():
        m = load(path)
        groups = ", ".join(f"{g.name} ({type(g.waveform).__name__})" for g in m.light_groups)
        print(f"{name:14s} {m.render.width}x{m.render.height} {m.duration_s * 1e3:.0f} ms  {groups}")
        print(f"{'':14s} {m.description}")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from gevsim.render import MitsubaScene, load, override, render_basis
    from gevsim.render.output import write_render

    manifest = load(args.scene)
    manifest = override(manifest, width=args.width, height=args.height, spp=args.spp, seed=args.seed,
                        noise_target_ln=args.noise_target, max_spp=args.max_spp, time_budget_s=args.time_budget,
                        denoise=args.denoise, duration_s=args.duration, source="command line")
    if args.plots and args.frames is None:
        raise ConfigError("--plots needs --frames RATE (the plots show the mixed sequence)", key="--plots")
    if args.plots:
        from gevsim.plots import _pyplot

        _pyplot()
    start = time.perf_counter()
    scene = MitsubaScene(manifest)
    r = manifest.render
    quality = (f"noise target {r.noise_target_ln} ln at p{r.noise_percentile:g} (max {r.max_spp} spp)" if r.targeted
               else f"{r.spp} spp")
    print(f"gevsim: scene {manifest.name}, {r.width}x{r.height}, {quality}, {r.sampler} sampler, "
          f"variant {scene.variant.variant} ({scene.variant.reason}), "
          f"{'one pass for all light groups' if scene.one_pass else 'one render per light group'}", file=sys.stderr)
    update, close = _progress(f"render {manifest.name}", not args.quiet)
    try:
        basis = render_basis(scene, cache_dir=args.cache, progress=update)
    finally:
        close()
    rendered = int((basis.render_s > 0).sum())
    info = write_render(args.out, manifest, basis, variant=scene.variant, frame_rate_hz=args.frames,
                        exposure_s=args.exposure, plots=args.plots)
    per = basis.render_s[basis.render_s > 0]
    timing = f", {per.mean():.2f} s per pose" if per.size else ""
    q = basis.noise_summary()
    print(f"gevsim: {len(basis.times_s)} poses x {len(basis.groups)} light groups, {rendered} poses rendered, "
          f"{basis.render_s.size - rendered} from cache{timing}; {q['spp_min']}-{q['spp_max']} spp, "
          f"p{q['percentile']:g} ln error {q['se_ln']['at_percentile']:.4g}"
          f"{'' if q['reached'] else ' (target NOT reached: ' + ', '.join(q['stopped_by']) + ')'}; "
          f"{len(info.get('frames', {}).get('t_s', []))} frames; wrote {args.out} "
          f"in {time.perf_counter() - start:.1f} s", file=sys.stderr)
    return 0


def _emulator_names(args: argparse.Namespace, choices=None) -> tuple[str, ...] | None:
    """``--emulators a,b`` as registry names (None when not given); unknown names are a ConfigError."""
    from gevsim.emulation.emulators import EMULATORS, check_emulator_list

    if args.emulators is None:
        return None
    try:
        return check_emulator_list([n.strip() for n in args.emulators.split(",") if n.strip()],
                                   tuple(choices or EMULATORS))
    except ValueError as exc:
        raise ConfigError(str(exc), key="--emulators") from None


def _render_overrides(args: argparse.Namespace) -> dict:
    return {k: v for k, v in (("width", args.width), ("height", args.height)) if v is not None}


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
    print(f"{'stream':20s} {'events':>10s} {'events/s':>11s} {'per pixel/s':>11s} {'p/frame':>8s} "
          f"{'emulator s':>10s}")
    for (name, count), seconds in zip(summary.counts.items(), summary.event_s.values()):
        st = stats[name]
        print(f"{name:20s} {count:10d} {st.rates_hz['total']:11.4g} {st.rates_hz['per_pixel_hz']:11.4g} "
              f"{st.event_probability:8.3f} {seconds:10.2f}")
    print(f"gevsim: wrote {args.out} in {summary.total_s:.1f} s", file=sys.stderr)
    return 0


def _emulate_frames(args: argparse.Namespace) -> int:
    from gevsim.emulation import run_frames
    from gevsim.io import frames as loaders

    if args.evreal is not None:
        frames, t_s = loaders.load_evreal_frames(args.evreal)
        source = args.evreal
    elif args.video is not None:
        frames, t_s = loaders.load_video(args.video, fps=args.fps)
        source = args.video
    else:
        frames, t_s = loaders.load_frame_folder(args.frames, fps=args.fps)
        source = args.frames
    from gevsim.emulation.emulators import FRAME_EMULATORS

    given = [flag for flag, value in (("--width", args.width), ("--height", args.height),
                                      ("--duration", args.duration)) if value is not None]
    if given:
        raise ConfigError(f"frame mode takes its size and times from the frames; drop {', '.join(given)}",
                          key=given[0])
    names = _emulator_names(args, FRAME_EMULATORS)
    if args.seed is not None and args.threshold_mismatch is None:
        raise ConfigError("--seed draws the DVS threshold mismatch: give --threshold-mismatch LN as well",
                          key="--seed")
    summary = run_frames(frames, t_s, args.out, seed=args.seed or 0, source=source,
                         emulators=names or FRAME_EMULATORS, threshold_mismatch_ln=args.threshold_mismatch or 0.0,
                         log_mode=args.log or "offset")
    print(f"{'stream':22s} {'events':>10s} {'events/s':>12s}")
    for name, count in summary["counts"].items():
        print(f"{name:22s} {count:10d} {count / summary['duration_s']:12.4g}")
    print(f"gevsim: {summary['frames']} frames {summary['width']}x{summary['height']} from {source}; "
          f"wrote {args.out}", file=sys.stderr)
    return 0


def cmd_reconstruct(args: argparse.Namespace) -> int:
    from gevsim.evaluation import reconstruct_file, write_reconstructions

    methods = [m.strip() for m in ",".join(args.method).split(",") if m.strip()]
    if not methods:
        from gevsim.evaluation.methods import METHODS

        raise ConfigError(f"no method named in {', '.join(map(repr, args.method))}; choose from "
                          f"{', '.join(METHODS)}", key="--method")
    results, gt, tone = [], None, None
    update, close = _progress("reconstruct", not args.quiet, unit="method")
    try:
        for k, method in enumerate(methods):
            rec, gt, tone = reconstruct_file(args.file, method, mean=args.mean, c=args.c, contrast_ln=args.contrast,
                                             reference=args.reference)
            results.append(rec)
            if update:
                update(k + 1, len(methods))
    finally:
        close()
    assert gt is not None and tone is not None  # at least one method ran
    settings = {"methods": methods, "mean": args.mean, "c": args.c, "contrast": args.contrast,
                "reference": args.reference}
    summary = write_reconstructions(args.out, args.file, results, gt, tone, settings=settings,
                                    bits_per_event=args.bits_per_event)
    print(f"{'method':16s} {'MSE':>8s} {'SSIM':>7s} {'PSNR dB':>8s} {'events/s':>10s} {'p/frame':>8s} "
          f"{'Mbit/s':>8s}   ({summary['frames']} frames)")
    for name, m in summary["methods"].items():
        b = summary["bandwidth"][name]
        print(f"{name:16s} {m['mse']:8.4f} {m['ssim']:7.3f} {m['psnr']:8.2f} {b['events_per_s']:10.4g} "
              f"{b['event_probability']:8.3f} {b['bits_per_s'] / 1e6:8.3f}")
    print(f"gevsim: wrote {args.out}", file=sys.stderr)
    return 0


def cmd_study(args: argparse.Namespace) -> int:
    import dataclasses

    from gevsim.experiments.executors import make_executor
    from gevsim.experiments.report import comparison_table, write_study_outputs
    from gevsim.experiments.study import check_study_scenes, load_study
    from gevsim.experiments.study_run import run_study
    from gevsim.io import exclusive

    study = load_study(args.config)
    base = dict(study.base)
    if args.repeats is not None:
        base["repeats"] = args.repeats
    if _render_overrides(args):
        base["render"] = {**base["render"], **_render_overrides(args)}
    if args.duration is not None:
        base["duration_s"] = args.duration
    if (names := _emulator_names(args)) is not None:
        from gevsim.evaluation.methods import METHODS

        missing = sorted({METHODS[m].emulator for m in base["methods"]} - set(names))
        if missing:
            raise ConfigError(f"the study's methods need the emulators {', '.join(missing)}", key="--emulators")
        base["emulators"] = list(names)
    study = dataclasses.replace(study, base=base)
    check_study_scenes(study)
    _quiet_dask(args)
    with exclusive(args.out, what="study"):  # a second study on this folder is refused before any work
        with make_executor(args.executor, workers=args.workers, scheduler=args.scheduler) as executor:
            update, close = _progress(f"study {study.name}", not args.quiet, unit="job")
            try:
                rows = run_study(study, args.out, cache_dir=args.cache, executor=executor, progress=update,
                                 keep_files=args.keep_files)
            finally:
                close()
        report = write_study_outputs(args.out, study, rows)
    print(comparison_table(rows, study))
    print(f"gevsim: {len(rows)} runs x {study.base['repeats']} repeats; report {report}", file=sys.stderr)
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from gevsim.io.aedat4 import export_aedat4

    streams = [s for part in args.stream or [] for s in part.split(",") if s] or None
    counts = export_aedat4(args.file, args.out, streams=streams)
    print(f"gevsim: wrote {args.out}: " + ", ".join(f"{k} {v}" for k, v in counts.items()), file=sys.stderr)
    return 0


def _quiet_dask(args: argparse.Namespace) -> None:
    """distributed sets its loggers to INFO on import: back to WARNING unless --verbose."""
    if args.executor != "dask" or args.verbose:
        return
    try:
        import distributed  # noqa: F401
    except ImportError:
        return  # make_executor says what to install
    for name in [n for n in logging.root.manager.loggerDict if n.split(".")[0] == "distributed"]:
        logging.getLogger(name).setLevel(logging.WARNING)


def cmd_dataset(args: argparse.Namespace) -> int:
    import dataclasses

    from gevsim.experiments.dataset import generate, load_dataset_config
    from gevsim.experiments.executors import make_executor
    from gevsim.io import exclusive

    config = load_dataset_config(args.config)
    changes: dict = {}
    if _render_overrides(args):
        changes["render"] = {**config.render, **_render_overrides(args)}
    if args.duration is not None:
        changes["time"] = dataclasses.replace(config.time, duration_s=args.duration)
    if (names := _emulator_names(args)) is not None:
        changes["emulators"] = names
    config = dataclasses.replace(config, **changes)
    _quiet_dask(args)
    with exclusive(args.out, what="dataset"), \
            make_executor(args.executor, workers=args.workers, scheduler=args.scheduler) as executor:
        update, close = _progress("dataset", not args.quiet, unit="seq")
        try:
            summary = generate(config, args.out, executor=executor, cache_dir=args.cache, progress=update)
        finally:
            close()
    print(f"gevsim: {summary['sequences']} sequences: {summary['done']} made, {summary['skipped']} already done; "
          f"{summary['events']} events ({', '.join(f'{k} {v}' for k, v in summary['counts'].items())}); "
          f"wrote {args.out} in {summary['seconds']:.1f} s", file=sys.stderr)
    return 0


def _int_at_least(low: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``low``."""
    wanted = {0: "a non-negative integer", 1: "a positive integer"}.get(low, f"an integer >= {low}")

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}")
        return value

    return parse


_positive_int = _int_at_least(1)
_non_negative_int = _int_at_least(0)


def _run_overrides(parser: argparse.ArgumentParser) -> None:
    """--width/--height/--duration/--emulators: override the config's values for this run."""
    parser.add_argument("--width", type=_positive_int, help="render width in pixels (overrides the config)")
    parser.add_argument("--height", type=_positive_int, help="render height in pixels (overrides the config)")
    parser.add_argument("--duration", type=_positive, metavar="S", help="duration in seconds (overrides the config)")
    parser.add_argument("--emulators", metavar="LIST", help="comma-separated emulators (overrides the config), "
                                                            "e.g. dvs,gradient")


def _executor_options(parser: argparse.ArgumentParser) -> None:
    from gevsim.experiments.executors import EXECUTORS

    parser.add_argument("--executor", choices=tuple(EXECUTORS), default="local",
                        help="local process pool (default) or Dask distributed")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address (default: a LocalCluster)")
    parser.add_argument("--workers", type=_positive_int, metavar="N",
                        help="worker processes (default: the number of CPUs)")


def build_parser() -> argparse.ArgumentParser:
    import gevsim

    parser = argparse.ArgumentParser(prog="gevsim", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"gevsim {gevsim.__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log gevsim's debug messages")
    sub = parser.add_subparsers(dest="command", required=True)
    # -v after the subcommand as well (``gevsim emulate cfg.toml -v``); not given there: the top level's value.
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                        help="log gevsim's debug messages")
    _add_parser = sub.add_parser

    def add_parser(*a, **kw):
        return _add_parser(*a, parents=[common], **kw)

    sub.add_parser = add_parser  # type: ignore[method-assign]

    sub.add_parser("info", help="versions, Mitsuba variant and why, libLLVM, threads").set_defaults(func=cmd_info)
    sub.add_parser("scenes", help="list the built-in scenes").set_defaults(func=cmd_scenes)
    sub.add_parser("presets", help="list the sensor presets and their main parameters").set_defaults(func=cmd_presets)

    r = sub.add_parser("render", help="render a scene's light-group basis images (and an irradiance sequence)")
    r.add_argument("scene", help="a built-in scene name (see `gevsim scenes`) or a manifest .toml")
    r.add_argument("--out", required=True, help="output folder (replaced atomically)")
    r.add_argument("--frames", type=_positive, metavar="RATE", help="also write the mixed irradiance at RATE frames/s")
    r.add_argument("--exposure", type=_positive, metavar="S",
                   help="average each frame over S seconds (default: instant)")
    r.add_argument("--plots", action="store_true", help="write contact_sheet.png and waveform.png (needs --frames)")
    r.add_argument("--cache", metavar="DIR", help="basis image cache (default $GEVSIM_CACHE or ~/.cache/gevsim)")
    r.add_argument("--width", type=int)
    r.add_argument("--height", type=int)
    r.add_argument("--spp", type=int, help="a fixed sample count (draft mode; replaces the scene's noise target)")
    r.add_argument("--noise-target", type=float, metavar="LN", dest="noise_target",
                   help="render until this standard error of ln radiance (at the scene's percentile) is reached")
    r.add_argument("--max-spp", type=int, dest="max_spp", help="noise-target mode: stop at this many samples")
    r.add_argument("--time-budget", type=float, metavar="S", dest="time_budget",
                   help="noise-target mode: stop after about S seconds of rendering")
    r.add_argument("--denoise", action=argparse.BooleanOptionalAction, default=None,
                   help="denoise the group images with Intel Open Image Denoise (biased; see benchmarks/README.md)")
    r.add_argument("--seed", type=_non_negative_int)
    r.add_argument("--duration", type=float, metavar="S", help="sequence duration in seconds")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=cmd_render)

    e = sub.add_parser("emulate", help="emulate events: a scene (CONFIG.toml) or a frame sequence")
    e.add_argument("config", nargs="?", help="emulation config (keys: docs/config.md)")
    e.add_argument("--out", required=True, help="output HDF5 file (written atomically)")
    e.add_argument("--frames", metavar="DIR", help="frame mode: a folder of images (+ timestamps.txt or --fps)")
    e.add_argument("--evreal", metavar="DIR", help="frame mode: an EVREAL sequence folder")
    e.add_argument("--video", metavar="FILE", help="frame mode: a video file (needs imageio)")
    e.add_argument("--fps", type=_positive, help="frame rate when the frames carry no timestamps")
    e.add_argument("--seed", type=_non_negative_int, help="frame mode: seed of the DVS threshold mismatch")
    e.add_argument("--threshold-mismatch", type=_non_negative, metavar="LN", dest="threshold_mismatch",
                   help="frame mode: sigma of the DVS threshold mismatch (ln units; default 0)")
    e.add_argument("--log", choices=("offset", "linlog"),
                   help="frame mode: the DVS sees ln(f + 1/255) (offset, default) or ln(f) above 20/255 and "
                        "its tangent below (linlog, as v2e's lin-log)")
    _run_overrides(e)
    e.add_argument("--no-flicker", action="store_true", help="replace every lamp waveform by its mean")
    e.add_argument("--no-noise", action="store_true", help="ideal pixel: no noise, no mismatch, no leak")
    e.add_argument("--cold-start", action="store_true", dest="cold_start",
                   help="start as if just switched on (default: a sensor that has been running)")
    e.add_argument("--cache", metavar="DIR", help="basis image cache")
    e.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    e.set_defaults(func=cmd_emulate)

    c = sub.add_parser("reconstruct", help="reconstruct frames from an emulation file and score them")
    c.add_argument("file", help="an HDF5 file written by `gevsim emulate`")
    c.add_argument("--method", action="append", required=True,
                   help="reconstruction methods by full name, as listed in gevsim.evaluation.METHODS: gradient "
                        "events dct, sor and dct_rc, sor_rc (resolution-compressed stream); brightness events "
                        "direct, high_pass, complementary; repeat or comma-separate")
    c.add_argument("--out", required=True, help="output folder (replaced atomically)")
    c.add_argument("--mean", default="ground-truth", help="level: ground-truth (papers' protocol) or photodiode")
    c.add_argument("--c", type=_positive, default=3.6, help="Poisson scale c (paper: 3.6 for three thresholds)")
    c.add_argument("--contrast", type=_positive, help="contrast step of a brightness event (ln units; default: "
                                                   "the sensor's DVS thresholds stored in the file)")
    c.add_argument("--reference", default="flicker",
                   help="ground truth: flicker (as lit at each instant) or no-flicker (lamps at their mean)")
    c.add_argument("--bits-per-event", type=_non_negative, default=32.0, help="for the bandwidth column (default 32)")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    c.set_defaults(func=cmd_reconstruct)

    x = sub.add_parser("export", help="write an emulation file's events in another format (AEDAT4 for DV tools)")
    x.add_argument("file", help="an emulation file (.h5)")
    x.add_argument("--format", choices=("aedat4",), required=True,
                   help="aedat4: iniVation DV (gradient axes as <stream>_x/_y event streams)")
    x.add_argument("--out", required=True, help="output file (written atomically)")
    x.add_argument("--stream", action="append", metavar="NAME", help="streams to export (default: all)")
    x.set_defaults(func=cmd_export)

    d = sub.add_parser("dataset", help="generate many randomised sequences (shards, EVREAL folders), resumable")
    d.add_argument("config", help="dataset config (keys: docs/config.md)")
    d.add_argument("--out", required=True, help="output folder; finished sequences in it are kept")
    _executor_options(d)
    _run_overrides(d)
    d.add_argument("--cache", metavar="DIR", help="basis image cache (shared by the workers)")
    d.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    d.set_defaults(func=cmd_dataset)

    v = sub.add_parser("validate", help="check sensor presets against published measurements (background activity, "
                       "bandwidth, latency, mismatch, readout) and against themselves (halved step, shifted start); "
                       "writes a report with plots and a pass/fail table")
    v.add_argument("--sensor", action="append", help="a preset name or TOML file (repeatable; default: every shipped "
                   "preset but 'ideal')")
    v.add_argument("--out", required=True, help="output folder (replaced atomically)")
    v.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    v.add_argument("--quick", action="store_true",
                   help="smaller, shorter runs (16x16 px, 3 s per point): wider intervals")
    v.set_defaults(func=cmd_validate)

    s = sub.add_parser("study", help="run (or resume) a study: sweeps with repeats and counterfactuals, intervals, "
                                     "plots and a report")
    s.add_argument("config", help="a study config (experiments/*.toml; keys: docs/config.md)")
    s.add_argument("--out", required=True, help="study folder (runs/ inside makes reruns resume)")
    s.add_argument("--repeats", type=_positive_int, metavar="R",
                   help="noise seeds per run (default: [study] repeats); more repeats reuse the finished ones")
    _executor_options(s)
    _run_overrides(s)
    s.add_argument("--cache", metavar="DIR", help="basis image cache (default with workers: OUT/render-cache)")
    s.add_argument("--keep-files", action="store_true", help="keep every run's HDF5 files")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_study)
    return parser


def cmd_validate(args: argparse.Namespace) -> int:
    from gevsim.pixel import load_preset
    from gevsim.pixel.presets import preset_names
    from gevsim.validation.checks import Settings
    from gevsim.validation.report import validate, write

    names = args.sensor or [n for n in preset_names() if n != "ideal"]
    presets = [load_preset(n) for n in names]  # every name checked before any run
    settings = Settings.quick() if args.quick else Settings()
    results = []
    for preset in presets:
        update, close = _progress(f"validate {preset.name}", not args.quiet, unit="check")
        try:
            rows, curves = validate(preset, settings=settings, progress=update)
        finally:
            close()
        results.append((preset, rows, curves))
        failed = [r for r in rows if r.verdict == "fail"]
        print(f"{preset.name}: {sum(r.verdict == 'pass' for r in rows)} passed, {len(failed)} failed"
              + "".join(f"\n  FAIL {r.check}: published {r.published}, model {r.model}" for r in failed))
    report = write(results, args.out, settings)
    print(f"gevsim: wrote {report}", file=sys.stderr)
    return 1 if any(r.verdict == "fail" for _, rows, _ in results for r in rows) else 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if args.verbose:  # gevsim's own debug messages, not those of every library it imports
        logging.getLogger("gevsim").setLevel(logging.DEBUG)
    try:
        return args.func(args)
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0
    except GevsimError as exc:  # bad input, or an optional extra (plot, dask, video) is missing
        if args.verbose:
            raise
        print(f"gevsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("gevsim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
