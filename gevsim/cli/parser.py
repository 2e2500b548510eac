"""The argument parser of every command (``main`` dispatches on ``args.command``)."""

from __future__ import annotations

import argparse
from typing import Any

from gevsim.cli._common import (
    _executor_options,
    _non_negative,
    _non_negative_int,
    _positive,
    _positive_int,
    _run_overrides,
)
from gevsim.cli.help import description

DESCRIPTION = "Command line of gevsim, a physically based event-camera emulator."


def build_parser() -> argparse.ArgumentParser:
    import gevsim

    parser = argparse.ArgumentParser(prog="gevsim", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"gevsim {gevsim.__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log gevsim's debug messages")
    sub = parser.add_subparsers(dest="command", required=True)
    # -v after the subcommand as well (``gevsim emulate cfg.toml -v``); not given there: the top level's value.
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                        help="log gevsim's debug messages")
    _add_parser = sub.add_parser

    def add_parser(name, **kw):
        return _add_parser(name, parents=[common], description=description(name),
                           formatter_class=argparse.RawDescriptionHelpFormatter, **kw)

    sub.add_parser = add_parser  # type: ignore[method-assign]

    for add in (_listings, _render, _emulate, _reconstruct, _export, _view, _dataset, _validate, _study, _train,
                _score):
        add(sub)
    return parser


def _listings(sub: Any) -> None:
    """The listing commands: info, scenes, presets."""
    sub.add_parser("info", help="versions, Mitsuba variant and why, libLLVM, threads")
    sub.add_parser("scenes", help="list the built-in scenes")
    sub.add_parser("presets", help="list the sensor presets and their main parameters")


def _render(sub: Any) -> None:
    """``gevsim render``."""
    r = sub.add_parser("render", help="render a scene's light-group basis images (and an irradiance sequence)")
    r.add_argument("scene", help="a built-in scene name (see `gevsim scenes`) or a manifest .toml")
    r.add_argument("--out", required=True, help="output folder: missing, empty or an earlier render (replaced "
                   "atomically); anything else is refused")
    r.add_argument("--frames", type=_positive, metavar="RATE", help="also write the mixed irradiance at RATE frames/s")
    r.add_argument("--exposure", type=_positive, metavar="S",
                   help="average each frame over S seconds (default: instant)")
    r.add_argument("--plots", action="store_true", help="write contact_sheet.png and waveform.png (needs --frames)")
    r.add_argument("--cache", metavar="DIR", help="basis image cache (default $GEVSIM_CACHE or ~/.cache/gevsim)")
    r.add_argument("--width", type=int, help="render width in pixels (overrides the scene's)")
    r.add_argument("--height", type=int, help="render height in pixels (overrides the scene's)")
    r.add_argument("--spp", type=int, help="a fixed sample count (draft mode; replaces the scene's noise target)")
    r.add_argument("--noise-target", type=float, metavar="LN", dest="noise_target",
                   help="render until this standard error of ln radiance (at the scene's percentile) is reached")
    r.add_argument("--max-spp", type=int, dest="max_spp", help="noise-target mode: stop at this many samples")
    r.add_argument("--time-budget", type=float, metavar="S", dest="time_budget",
                   help="noise-target mode: stop after about S seconds of rendering")
    r.add_argument("--denoise", action=argparse.BooleanOptionalAction, default=None,
                   help="denoise the group images with Intel Open Image Denoise (biased; see benchmarks/README.md)")
    r.add_argument("--seed", type=_non_negative_int, help="seed of the renderer's samples (default: the scene's)")
    r.add_argument("--duration", type=float, metavar="S", help="sequence duration in seconds")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _emulate(sub: Any) -> None:
    """``gevsim emulate``."""
    e = sub.add_parser("emulate", help="emulate events: a scene (CONFIG.toml) or a frame sequence")
    e.add_argument("config", nargs="?", help="emulation config (keys: docs/config.md)")
    e.add_argument("--out", required=True, help="output HDF5 file (written atomically; replaces only an earlier "
                   "gevsim event file)")
    e.add_argument("--frames", metavar="DIR", help="frame mode: a folder of images (+ timestamps.txt or --fps)")
    e.add_argument("--evreal", metavar="DIR", help="frame mode: an EVREAL sequence folder")
    e.add_argument("--video", metavar="FILE", help="frame mode: a video file (needs imageio)")
    e.add_argument("--fps", type=_positive, help="frame rate when the frames carry no timestamps")
    e.add_argument("--seed", type=_non_negative_int, help="frame mode: seed of the DVS threshold mismatch")
    e.add_argument("--threshold-mismatch", type=_non_negative, metavar="LN", dest="threshold_mismatch",
                   help="frame mode: sigma of the DVS threshold mismatch (ln units; default 0)")
    e.add_argument("--sensor", metavar="NAME", help="frame mode through a real sensor: a preset (ideal, dvs128, "
                   "davis346, imx636) or preset file; the frames become light on the chip (with "
                   "--illuminance-lux) and the scene-mode pixel runs on them: photoreceptor, noise, bandwidth, "
                   "leak, refractory period, readout. Without it: the paper's frame mode")
    e.add_argument("--illuminance-lux", type=_positive, metavar="LUX", dest="illuminance_lux",
                   help="with --sensor: the chip illuminance (lux) of a frame value of 1 after sRGB decoding "
                        "(D65 light)")
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


def _reconstruct(sub: Any) -> None:
    """``gevsim reconstruct``."""
    c = sub.add_parser("reconstruct", help="reconstruct frames from an emulation file and score them")
    c.add_argument("file", help="an HDF5 file written by `gevsim emulate`")
    c.add_argument("--method", action="append", required=True,
                   help="reconstruction methods by full name, as listed in gevsim.evaluation.METHODS: gradient "
                        "events dct, sor and dct_rc, sor_rc (resolution-compressed stream); brightness events "
                        "direct, high_pass, complementary; repeat or comma-separate")
    c.add_argument("--out", required=True, help="output folder: missing, empty or an earlier reconstruction "
                   "(replaced atomically); anything else is refused")
    c.add_argument("--mean", default="ground-truth", help="level: ground-truth (papers' protocol) or photodiode")
    c.add_argument("--c", type=_positive, default=3.6, help="Poisson scale c (paper: 3.6 for three thresholds)")
    c.add_argument("--contrast", type=_positive, help="contrast step of a brightness event (ln units; default: "
                                                   "the sensor's DVS thresholds stored in the file)")
    c.add_argument("--reference", default="flicker",
                   help="ground truth: flicker (as lit at each instant) or no-flicker (lamps at their mean)")
    c.add_argument("--bits-per-event", type=_non_negative, default=32.0, help="for the bandwidth column (default 32)")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _export(sub: Any) -> None:
    """``gevsim export``."""
    x = sub.add_parser("export", help="write an emulation file's events in the formats other tools read")
    x.add_argument("file", help="an emulation file (.h5)")
    x.add_argument("--format", choices=("aedat4", "text", "npz", "evreal"), required=True,
                   help="aedat4: iniVation DV (the DVS stream 'events' first; others events_<kind>, gradient axes "
                        "as events_<kind>_x/_y); text: one stream as 't x y p' lines, t in seconds (ESIM, E2VID, "
                        "EVREAL tooling); npz: NumPy structured arrays with tonic's fields, one per stream; "
                        "evreal: an EVREAL sequence folder (DVS events and tone-mapped ground-truth frames)")
    x.add_argument("--out", required=True, help="output file (a folder for evreal; written atomically; replaces "
                   "only an earlier gevsim export of that format, never the input)")
    x.add_argument("--stream", action="append", metavar="NAME", help="streams to export (default: all)")
    x.add_argument("--header", choices=("gevsim", "e2vid"),
                   help="text only: the first line; gevsim (default): a '#' comment naming the columns; e2vid: "
                        "the sensor size 'W H', where E2VID reads it (brightness streams; such a file is never "
                        "replaced by a later export)")


def _view(sub: Any) -> None:
    """``gevsim view``."""
    v = sub.add_parser("view", help="draw an emulation file's events as pictures beside the ground truth "
                       "(.png strip, .gif or .mp4 animation)")
    v.add_argument("file", help="an emulation file (.h5)")
    v.add_argument("--out", required=True, help="a .png (up to 8 windows, one under the other), .gif or .mp4 "
                   "(every window; .mp4 needs imageio-ffmpeg); replaces only an earlier `gevsim view` picture")
    # Numbers are checked by gevsim.view (finite, in range, fps within what the format stores): one error line.
    v.add_argument("--window-ms", type=float, default=1.0, help="time window of one picture, ms (default 1)")
    v.add_argument("--start-ms", type=float, default=0.0, help="where the first window starts, ms (default 0)")
    v.add_argument("--end-ms", type=float, help="where the last window ends, ms (default: the file's end)")
    v.add_argument("--streams", action="append", metavar="NAMES", help="streams to draw (default: all)")
    v.add_argument("--fps", type=float, default=10.0, help="animation frames per second (default 10; "
                   ".gif 0.01 to 100, .mp4 0.01 to 1000)")
    v.add_argument("--max-frames", type=int, metavar="N",
                   help="refuse a view of more windows than this (default 10000: a longer --window-ms, "
                   "or --start-ms/--end-ms, fit a long file)")


def _dataset(sub: Any) -> None:
    """``gevsim dataset``."""
    d = sub.add_parser("dataset", help="generate many randomised sequences (shards, EVREAL folders), resumable")
    d.add_argument("config", help="dataset config (keys: docs/config.md)")
    d.add_argument("--out", required=True, help="output folder (missing, empty or an earlier dataset); finished "
                   "sequences in it are kept")
    _executor_options(d)
    _run_overrides(d)
    d.add_argument("--cache", metavar="DIR", help="basis image cache (shared by the workers)")
    _part_options(d, "sequences j", "OUT/dataset.json")
    d.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _part_options(parser: argparse.ArgumentParser, items: str, result: str) -> None:
    """--part I/N and --merge of ``dataset`` and ``study`` (docs/cluster.md)."""
    parser.add_argument("--part", metavar="I/N", help=f"make only part I of N ({items} with j %% N == I), e.g. "
                        f"$SLURM_ARRAY_TASK_ID/N in an array job, in OUT.parts/I-of-N; the part that finishes last "
                        f"merges every part into OUT and writes {result} (docs/cluster.md)")
    parser.add_argument("--merge", action="store_true", help="only merge what the --part runs finished into OUT "
                        f"and write {result}; make nothing")


def _validate(sub: Any) -> None:
    """``gevsim validate``."""
    v = sub.add_parser("validate", help="check sensor presets against published measurements (background activity, "
                       "bandwidth, latency, mismatch, readout) and against themselves (halved step, shifted start); "
                       "writes a report with plots and a pass/fail table")
    v.add_argument("--sensor", action="append", help="a preset name or TOML file (repeatable; default: every shipped "
                   "preset but 'ideal')")
    v.add_argument("--out", required=True, help="output folder: missing, empty or an earlier validation report "
                   "(replaced atomically)")
    v.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    v.add_argument("--quick", action="store_true",
                   help="smaller, shorter runs (16x16 px, 3 s per point): wider intervals")


def _study(sub: Any) -> None:
    """``gevsim study``."""
    s = sub.add_parser("study", help="run (or resume) a study: sweeps with repeats and counterfactuals, intervals, "
                                     "plots and a report")
    s.add_argument("config", help="a study config (experiments/*.toml; keys: docs/config.md)")
    s.add_argument("--out", required=True, help="study folder: missing, empty or an earlier study (runs/ inside "
                   "makes reruns resume)")
    s.add_argument("--repeats", type=_positive_int, metavar="R",
                   help="noise seeds per run (default: [study] repeats); more repeats reuse the finished ones")
    _executor_options(s)
    _run_overrides(s)
    s.add_argument("--cache", metavar="DIR", help="basis image cache (default with workers: OUT/render-cache)")
    s.add_argument("--keep-files", action="store_true", help="keep every run's HDF5 files")
    _part_options(s, "jobs j, a job being one repeat of one run", "the report")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _train(sub: Any) -> None:
    """``gevsim train``."""
    t = sub.add_parser("train", help="train the learned reconstruction on a `gevsim dataset` (needs gevsim[learn])")
    t.add_argument("--events", required=True, choices=("dvs", "gradient", "gradient_rc"),
                   help="the event stream and its input encoding")
    t.add_argument("--data", required=True, nargs="+", metavar="DIR",
                   help="a `gevsim dataset` folder (its shards/seq_*.h5) or emulation files (.h5)")
    t.add_argument("--out", required=True, help="the weights (.npz; replaces only earlier gevsim weights), with "
                   "their provenance (.json) and loss curve (.png) beside them")
    t.add_argument("--minutes", type=_positive, default=10.0, help="training time budget (default 10)")
    t.add_argument("--steps", type=_positive_int, help="stop after this many steps (before the budget ends)")
    t.add_argument("--seed", type=_non_negative_int, default=0, help="seed of the weights, split and batches")
    t.add_argument("--reference", default="flicker", choices=("flicker", "no-flicker"),
                   help="ground truth: as lit at each instant (flicker) or with every lamp at its mean")
    t.add_argument("--threads", type=_positive_int, help="PyTorch threads (default: PyTorch's)")
    t.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _score(sub: Any) -> None:
    """``gevsim score``."""
    s = sub.add_parser("score", help="score reconstruction methods over many emulation files (a dataset's shards)")
    s.add_argument("files", nargs="+", metavar="PATH", help="emulation files (.h5) or `gevsim dataset` folders")
    s.add_argument("--method", action="append", required=True,
                   help="reconstruction methods by full name (as for `gevsim reconstruct`); repeat or comma-separate")
    s.add_argument("--reference", default="flicker",
                   help="ground truths, comma-separated: flicker (as lit) and/or no-flicker (lamps at their mean)")
    s.add_argument("--out", required=True, help="output folder: missing, empty or an earlier gevsim reconstruction "
                   "output (replaced atomically); anything else is refused")
    s.add_argument("--c", type=_positive, default=3.6, help="Poisson scale c of the gradient methods (paper: 3.6)")
    s.add_argument("--title", help="the table's and plot's title (default: the number of sequences)")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
