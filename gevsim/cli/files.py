"""``gevsim reconstruct``, ``score``, ``view`` and ``export``: commands that read emulation files."""

from __future__ import annotations

import argparse
import sys

from gevsim.cli._common import _progress
from gevsim.errors import ConfigError


def cmd_reconstruct(args: argparse.Namespace) -> int:
    from gevsim.evaluation import reconstruct_file, write_reconstructions
    from gevsim.io.ownership import check_folder
    from gevsim.resources import check_writable

    methods = [m.strip() for m in ",".join(args.method).split(",") if m.strip()]
    if not methods:
        from gevsim.evaluation.methods import METHODS

        raise ConfigError(f"no method named in {', '.join(map(repr, args.method))}; choose from "
                          f"{', '.join(METHODS)}", key="--method")
    check_folder(args.out, "reconstruction", inputs=[args.file])  # before the work: only an earlier one is replaced
    check_writable(args.out)
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


def cmd_view(args: argparse.Namespace) -> int:
    from gevsim.view import MAX_FRAMES, ms_to_us, view

    streams = [s for part in args.streams or [] for s in part.split(",") if s] or None
    end_us = None if args.end_ms is None else ms_to_us(args.end_ms, "--end-ms")
    out = view(args.file, args.out, window_us=ms_to_us(args.window_ms, "--window-ms"), streams=streams,
               fps=args.fps, start_us=ms_to_us(args.start_ms, "--start-ms"), end_us=end_us,
               max_frames=MAX_FRAMES if args.max_frames is None else args.max_frames)
    played = ""
    if str(out).lower().endswith(".gif"):  # a GIF stores whole 1/100 s delays: say where --fps was rounded
        from gevsim.view_writer import gif_delay_ms

        fps = 1000.0 / gif_delay_ms(args.fps)
        if abs(fps - args.fps) > 1e-3 * args.fps:
            played = f" (a GIF stores whole 1/100 s: it plays at {fps:.3g} fps, not {args.fps:g})"
    print(f"gevsim: wrote {out}{played}", file=sys.stderr)
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from gevsim.io.exports import export

    streams = [s for part in args.stream or [] for s in part.split(",") if s] or None
    counts = export(args.file, args.out, args.format, streams=streams, header=args.header)
    print(f"gevsim: wrote {args.out}: " + ", ".join(f"{k} {v}" for k, v in counts.items()), file=sys.stderr)
    return 0


def cmd_score(args: argparse.Namespace) -> int:
    from gevsim.evaluation.compare import emulation_files, score_files, summarize, table_markdown, write_comparison
    from gevsim.evaluation.methods import check_method
    from gevsim.io.ownership import check_folder
    from gevsim.resources import check_writable

    methods = [m.strip() for m in ",".join(args.method).split(",") if m.strip()]
    refs = [r.strip() for r in args.reference.split(",") if r.strip()]
    for m in methods:
        try:
            check_method(m)
        except ValueError as exc:
            raise ConfigError(str(exc), key="--method") from None
    if not methods or not refs:
        raise ConfigError("name at least one method and one reference",
                          key="--method" if not methods else "--reference")
    files = emulation_files(args.files)
    check_folder(args.out, "reconstruction", inputs=files)  # before the work: only an earlier one is replaced
    check_writable(args.out)
    update, close = _progress("score", not args.quiet, unit="run")
    try:
        rows = score_files(files, methods, refs, c=args.c, progress=update)
    finally:
        close()
    summary = summarize(rows)
    title = args.title or f"{len(files)} sequences"
    write_comparison(args.out, rows, summary, title=title, inputs=files)
    print(f"{title}\n\n{table_markdown(summary)}", end="")
    print(f"gevsim: wrote {args.out}", file=sys.stderr)
    return 0
