"""The held-out reconstruction comparison of issue 38: every method on sequences the networks never saw.

    .venv/bin/python experiments/learned_comparison.py [--out out/learned_comparison] [--quick]

1. Planar scenes with the held-out textures (scikit-image's chelsea, rocket, coffee and matplotlib's
   grace_hopper, never used in training) and other trajectories and lamps than the training set:
   ``experiments/heldout_planar.toml`` (flickering lamps) and ``heldout_planar_dc.toml`` (steady lamps), made
   by ``gevsim dataset`` and scored against both ground truths (as lit, and every lamp at its mean).
2. The paper's frame mode on the same four photographs, panned (:func:`panned`), scored against the frames.

Each part's table, plot and rows go to ``OUT/<part>/`` (``table.md``, ``ssim.png``, ``results.json``); the
dataset folders to ``OUT/data/``. Re-running reuses finished sequences (``gevsim dataset`` resumes).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SCENE_METHODS = ["e2v", "direct", "high_pass", "complementary", "e2v_gradient", "dct", "sor", "e2v_gradient_rc",
                 "dct_rc"]
FRAME_METHODS = ["e2v", "direct", "high_pass", "e2v_gradient", "dct", "sor", "e2v_gradient_rc", "dct_rc"]


def panned(photo: np.ndarray, *, width: int, height: int, frames: int, speed_px: float) -> np.ndarray:
    """``frames`` windows of ``height`` x ``width`` sliding right-and-down across ``photo`` (gray, [0, 1]) by
    ``speed_px`` per frame along the diagonal's direction, linearly interpolated (sub-pixel shifts)."""
    h, w = photo.shape
    span_x, span_y = w - width - 1, h - height - 1
    norm = float(np.hypot(span_x, span_y))
    ux, uy = span_x / norm, span_y / norm
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    out = np.empty((frames, height, width))
    for k in range(frames):
        x, y = xs + k * speed_px * ux, ys + k * speed_px * uy
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - x0, y - y0
        out[k] = ((1 - fy) * ((1 - fx) * photo[y0, x0] + fx * photo[y0, x0 + 1])
                  + fy * ((1 - fx) * photo[y0 + 1, x0] + fx * photo[y0 + 1, x0 + 1]))
    return np.clip(np.round(out * 255.0) / 255.0, 0.0, 1.0)  # 8-bit frames, as a video would give


def _dataset(config: Path, out: Path, quick: bool) -> Path:
    cmd = [sys.executable, "-m", "gevsim.cli", "dataset", str(config), "--out", str(out), "-q"]
    if quick:
        cmd += ["--part", "0/6"]  # a sixth of the sequences (a smoke run)
    subprocess.run(cmd, check=True)
    return out if not quick else Path(f"{out}.parts") / "0-of-6"


def _frame_files(out: Path, *, quick: bool) -> list[Path]:
    from gevsim.emulation.frames import run_frames
    from gevsim.learn.textures import HELD_OUT, texture

    out.mkdir(parents=True, exist_ok=True)
    files = []
    for name in HELD_OUT:
        frames = panned(texture(name), width=128, height=96, frames=8 if quick else 25, speed_px=2.0)
        path = out / f"{name}.h5"
        run_frames(frames, np.arange(len(frames)) / 100.0, path, source=f"{name} panned 2 px/frame")
        files.append(path)
    return files


def main(argv: list[str] | None = None) -> int:
    from gevsim.cli._common import _progress
    from gevsim.evaluation.compare import emulation_files, score_files, summarize, write_comparison

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="out/learned_comparison")
    p.add_argument("--quick", action="store_true", help="a smoke run: few sequences and frames")
    args = p.parse_args(argv)
    out = Path(args.out)
    parts = {}
    for label, config in (("planar_flicker", "heldout_planar.toml"), ("planar_dc", "heldout_planar_dc.toml")):
        folder = _dataset(HERE / config, out / "data" / label, args.quick)
        parts[label] = (emulation_files([folder]), SCENE_METHODS, ("flicker", "no-flicker"))
    parts["frames"] = (_frame_files(out / "data" / "frames", quick=args.quick), FRAME_METHODS, ("flicker",))
    for label, (files, methods, refs) in parts.items():
        update, close = _progress(f"score {label}", True, unit="run")
        try:
            rows = score_files(files, methods, refs, progress=update)
        finally:
            close()
        summary = summarize(rows)
        title = f"Held-out {label}: {len(files)} sequences"
        write_comparison(out / label, rows, summary, title=title, inputs=files)
        print(f"{title}\n" + (out / label / "table.md").read_text().split("\n", 2)[2])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
