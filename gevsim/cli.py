"""Command line: ``gevsim info``, ``gevsim render``, ``gevsim scenes``.

The CLI parses arguments, sets up logging and progress bars and calls the
library. Bad input prints one line naming the file and key and exits with
code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time

from gevsim.errors import ConfigError

log = logging.getLogger("gevsim")


def _progress(desc: str, enabled: bool):
    """A ``progress(done, total)`` callback drawing a tqdm bar (or nothing)."""
    if not enabled:
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(desc=desc, unit="pose", leave=True, dynamic_ncols=True)

    def update(done: int, total: int) -> None:
        bar.total = total
        bar.n = done
        bar.refresh()

    return update, bar.close


def cmd_info(args) -> int:
    from gevsim.render.backend import describe

    for key, value in describe().items():
        print(f"{key:>9}: {value}")
    return 0


def cmd_scenes(args) -> int:
    from gevsim.render import builtin_scenes, load

    for name, path in builtin_scenes().items():
        m = load(path)
        groups = ", ".join(f"{g.name} ({type(g.waveform).__name__})" for g in m.light_groups)
        print(f"{name:14s} {m.render.width}x{m.render.height} {m.duration_s * 1e3:.0f} ms  {groups}")
        print(f"{'':14s} {m.description}")
    return 0


def cmd_render(args) -> int:
    from gevsim.render import MitsubaScene, load, override, render_basis
    from gevsim.render.output import write_render

    manifest = load(args.scene)
    manifest = override(manifest, width=args.width, height=args.height, spp=args.spp, seed=args.seed,
                        duration_s=args.duration)
    if args.frames is not None and args.frames <= 0:
        raise ConfigError(f"must be > 0, got {args.frames}", key="--frames")
    if args.plots and args.frames is None:
        raise ConfigError("--plots needs --frames RATE (the plots show the mixed sequence)", key="--plots")
    if args.plots:
        from gevsim.plots import _pyplot

        _pyplot()
    start = time.perf_counter()
    scene = MitsubaScene(manifest)
    print(f"gevsim: scene {manifest.name}, {manifest.render.width}x{manifest.render.height}, "
          f"{manifest.render.spp} spp, variant {scene.variant.variant} ({scene.variant.reason})", file=sys.stderr)
    update, close = _progress(f"render {manifest.name}", not args.quiet)
    try:
        basis = render_basis(scene, cache_dir=args.cache, progress=update)
    finally:
        close()
    rendered = int((basis.render_s > 0).sum())
    info = write_render(args.out, manifest, basis, variant=scene.variant, frame_rate_hz=args.frames,
                        exposure_s=args.exposure, plots=args.plots)
    per = basis.render_s[basis.render_s > 0]
    timing = f", {per.mean():.3f} s per basis image" if per.size else ""
    print(f"gevsim: {len(basis.times_s)} poses x {len(basis.groups)} light groups, {rendered} rendered, "
          f"{basis.render_s.size - rendered} from cache{timing}; "
          f"{len(info.get('frames', {}).get('t_s', []))} frames; wrote {args.out} "
          f"in {time.perf_counter() - start:.1f} s", file=sys.stderr)
    return 0


def build_parser() -> argparse.ArgumentParser:
    import gevsim

    parser = argparse.ArgumentParser(prog="gevsim", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"gevsim {gevsim.__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", required=True)

    sub.add_parser("info", help="versions, Mitsuba variant and why, libLLVM, threads").set_defaults(func=cmd_info)
    sub.add_parser("scenes", help="list the built-in scenes").set_defaults(func=cmd_scenes)

    r = sub.add_parser("render", help="render a scene's light-group basis images (and an irradiance sequence)")
    r.add_argument("scene", help="a built-in scene name (see `gevsim scenes`) or a manifest .toml")
    r.add_argument("--out", required=True, help="output folder (replaced atomically)")
    r.add_argument("--frames", type=float, metavar="RATE", help="also write the mixed irradiance at RATE frames/s")
    r.add_argument("--exposure", type=float, metavar="S", help="average each frame over S seconds (default: instant)")
    r.add_argument("--plots", action="store_true", help="write contact_sheet.png and waveform.png (needs --frames)")
    r.add_argument("--cache", metavar="DIR", help="basis image cache (default $GEVSIM_CACHE or ~/.cache/gevsim)")
    r.add_argument("--width", type=int)
    r.add_argument("--height", type=int)
    r.add_argument("--spp", type=int)
    r.add_argument("--seed", type=int)
    r.add_argument("--duration", type=float, metavar="S", help="sequence duration in seconds")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=cmd_render)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return args.func(args)
    except (ConfigError, ValueError, TypeError, OSError) as exc:
        if args.verbose:
            raise
        print(f"gevsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("gevsim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
