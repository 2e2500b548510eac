"""Write reconstructions: PNG frames, a metrics table (CSV and JSON) and a
side-by-side PNG of ground truth and each method, staged and renamed into
place like every gevsim output folder."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

import gevsim
from gevsim.io import MANIFEST, atomic_dir
from gevsim.io.ownership import check_name
from gevsim.tonemap import ToneMap


def _png(path: Path, image01: np.ndarray) -> None:
    import imageio.v3 as iio

    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, np.rint(np.clip(image01, 0, 1) * 255).astype(np.uint8))


def side_by_side(path: Path, gt01: np.ndarray, recs01: dict, t_us: np.ndarray, *, max_frames: int = 4,
                 metrics: dict | None = None) -> None:
    """Rows: a few frames; columns: ground truth, then each method (with its SSIM)."""
    from gevsim.plots import _pyplot, save_figure

    plt = _pyplot()
    idx = np.unique(np.linspace(0, len(gt01) - 1, min(max_frames, len(gt01))).round().astype(int))
    cols = 1 + len(recs01)
    h, w = gt01.shape[1:]
    fig, axes = plt.subplots(len(idx), cols, figsize=(2.6 * cols, 2.6 * len(idx) * h / w + 0.5), squeeze=False)
    for row, k in enumerate(idx):
        panels = [("ground truth", gt01[k])] + [(name, rec[k]) for name, rec in recs01.items()]
        for col, (name, img) in enumerate(panels):
            ax = axes[row, col]
            ax.imshow(img, cmap="gray", vmin=0, vmax=1)
            ax.axis("off")
            label = name if col == 0 else f"{name}\nSSIM {metrics[name][k]['ssim']:.3f}" if metrics else name
            ax.set_title(f"{label}" + (f"\nt = {t_us[k] / 1e3:.1f} ms" if col == 0 else ""), fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def write_reconstructions(out: str | Path, source: str | Path, results: list, gt: np.ndarray,
                          tone: ToneMap, *, settings: dict, bits_per_event: float = 32.0) -> dict:
    """Write every method's frames and scores, with the bandwidth of the event stream each
    method used (events/s, event probability per frame, bits/s at ``bits_per_event``);
    returns the summary (also manifest.json)."""
    from gevsim.emulation.summary import summarize
    from gevsim.metrics import bits_per_second

    streams = summarize(source)
    gt01 = tone(gt)
    recs01 = {r.method: tone(r.frames) for r in results}
    per_frame = {name: r.metrics for name, r in zip(recs01, results)}
    summary: dict[str, Any] = {
        "gevsim": gevsim.__version__,
        "source": str(source),
        "settings": settings,
        "tone_map": {"low": tone.low, "high": tone.high},
        "frames": len(gt),
        "methods": {name: r.mean_metrics() for name, r in zip(recs01, results)},
        "bandwidth": {},
        "bits_per_event": bits_per_event,
    }
    bandwidth: dict[str, dict] = summary["bandwidth"]
    for name, r in zip(recs01, results):
        st = streams[r.stream]
        bandwidth[name] = {
            "stream": r.stream,
            "events_per_s": st.rates_hz["total"],
            "event_probability": st.event_probability,
            "bits_per_s": float(bits_per_second(st.rates_hz["total"], bits_per_event=bits_per_event)),
        }
    for name in recs01:
        check_name(name, key="method")  # a path part below
    with atomic_dir(out, kind="reconstruction", inputs=[source]) as stage:
        for name, frames in recs01.items():
            for k, img in enumerate(frames):
                _png(stage / "frames" / name / f"{k:05d}.png", img)
        for k, img in enumerate(gt01):
            _png(stage / "frames" / "ground_truth" / f"{k:05d}.png", img)
        rows = io.StringIO()
        writer = csv.writer(rows)
        writer.writerow(["method", "frame", "t_us", "mse", "ssim", "psnr"])
        for name, r in zip(recs01, results):
            for k, m in enumerate(r.metrics):
                writer.writerow([name, k, int(r.t_us[k]), m["mse"], m["ssim"], m["psnr"]])
        (stage / "metrics.csv").write_text(rows.getvalue())
        (stage / "metrics.json").write_text(json.dumps({"summary": summary, "per_frame": per_frame}, indent=1,
                                                       default=float))
        side_by_side(stage / "side_by_side.png", gt01, recs01, results[0].t_us, metrics=per_frame)
        (stage / MANIFEST).write_text(json.dumps(summary, indent=2))
    return summary
