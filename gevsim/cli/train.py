"""``gevsim train``: train the learned reconstruction on a `gevsim dataset` (needs the ``learn`` extra)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from gevsim.cli._common import _progress
from gevsim.errors import ConfigError, MissingExtraError


def _is_provenance(path: Path) -> bool:
    try:
        return json.loads(path.read_text()).get("format") == "gevsim-training-provenance"
    except (OSError, ValueError, AttributeError):
        return False


def _is_loss_plot(path: Path) -> bool:
    try:
        from PIL import Image

        from gevsim.learn.train import PLOT_MARK

        with Image.open(path) as img:
            return img.info.get("Software") == PLOT_MARK
    except (OSError, ValueError, ImportError):
        return False


def _check_outputs(out: Path, inputs: list) -> None:
    """The weights, their provenance and loss curve replace only the files of an earlier `gevsim train`."""
    from gevsim.io.ownership import check_file
    from gevsim.learn.model import is_model_file

    if out.suffix != ".npz":
        raise ConfigError(f"the weights are an .npz file, got {out.name!r}", source=str(out), key="--out")
    check_file(out, "weight", is_model_file, inputs=inputs)
    check_file(out.with_suffix(".json"), "training provenance", _is_provenance, inputs=inputs)
    check_file(out.with_suffix(".png"), "loss curve", _is_loss_plot, inputs=inputs)


def cmd_train(args: argparse.Namespace) -> int:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise MissingExtraError("gevsim train needs PyTorch: pip install 'gevsim[learn]'") from None
    from gevsim.evaluation.compare import emulation_files
    from gevsim.learn.train import TrainSettings, train, write_outputs
    from gevsim.learn.train_data import data_digest, load_sequences
    from gevsim.plots import _pyplot

    _pyplot()  # the loss curve needs matplotlib: say so before the work
    out = Path(args.out)
    files = emulation_files(args.data)
    _check_outputs(out, [*args.data, *files])
    settings = TrainSettings(encoding=args.events, seed=args.seed, minutes=args.minutes, steps=args.steps,
                             threads=args.threads)
    update, close = _progress("encode", not args.quiet, unit="sequence")
    try:
        sequences = load_sequences(files, args.events, reference=args.reference, progress=update)
    finally:
        close()
    update, close = _progress("train", not args.quiet, unit="step" if args.steps else "second")

    def progress(step: int, elapsed_s: float, loss: float) -> None:
        if update:
            update(*((step, args.steps) if args.steps else (min(int(elapsed_s), int(60 * args.minutes)),
                                                             int(60 * args.minutes))))

    try:
        result = train(sequences, settings, progress=progress)
    finally:
        close()
    meta = write_outputs(result, settings, out, data_digest(args.data, files))
    val = meta["final_validation_loss"]
    print(f"gevsim: wrote {out} ({meta['steps']} steps in {meta['wall_s']:.0f} s, training loss "
          f"{meta['final_train_loss']:.4f}, validation loss {'-' if val is None else f'{val:.4f}'})",
          file=sys.stderr)
    return 0
