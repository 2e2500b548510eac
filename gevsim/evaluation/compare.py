"""Score reconstruction methods over many emulation files (a held-out dataset's shards): per method and ground
truth (as lit, or with every lamp at its mean), the mean MSE and SSIM over the sequences with a 95 % interval,
a table and a plot (``gevsim score``).

Each sequence is scored as ``gevsim reconstruct`` scores one file (:func:`gevsim.evaluation.reconstruct_file`:
EVREAL's protocol, every frame, the level set from the ground truth); a method's figure is the mean over
sequences of its per-sequence mean. The interval is Student's t over those sequence means (sequences are
independent draws of the dataset's generator; frames within one are not independent).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from gevsim.errors import ConfigError
from gevsim.evaluation.runner import REFERENCES, reconstruct_file

__all__ = ["emulation_files", "paired_difference", "score_files", "summarize", "table_markdown", "write_comparison"]


def emulation_files(paths: Iterable[str | os.PathLike]) -> list[Path]:
    """The emulation files named by ``paths``: each an .h5 file, or a ``gevsim dataset`` folder (its
    ``shards/seq_*.h5``, in order). ConfigError naming a path that is neither, or a folder without shards."""
    files: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            shards = sorted((p / "shards").glob("seq_*.h5"))
            if not shards:
                raise ConfigError("holds no shards/seq_*.h5: give emulation files or a `gevsim dataset` folder",
                                  source=str(p))
            files += shards
        elif p.is_file():
            files.append(p)
        else:
            raise ConfigError("no such file or folder", source=str(p))
    if not files:
        raise ConfigError("no emulation file given")
    return files


def score_files(files: Sequence[Path], methods: Sequence[str], references: Sequence[str] = ("flicker",), *,
                c: float = 3.6, progress: Callable[[int, int], None] | None = None) -> list[dict]:
    """One row per file, method and reference: the file's mean ``mse``, ``ssim`` and ``psnr`` over its frames
    (``c``: the Poisson scale of the gradient methods, as ``gevsim reconstruct --c``)."""
    for ref in references:
        if ref not in REFERENCES:
            raise ConfigError(f"unknown reference {ref!r}; choose from {', '.join(REFERENCES)}", key="--reference")
    rows, total = [], len(files) * len(methods) * len(references)
    for f in files:
        for method in methods:
            for ref in references:
                rec, gt, _ = reconstruct_file(f, method, reference=ref, c=c)
                rows.append({"file": str(f), "method": method, "reference": ref, "c": c, "frames": int(len(gt)),
                             **rec.mean_metrics()})
                if progress is not None:
                    progress(len(rows), total)
    return rows


def _interval(values: np.ndarray) -> tuple[float, float]:
    """(mean, half-width of the 95 % Student-t interval); the half-width is nan for fewer than two values."""
    from scipy.stats import t

    mean = float(np.mean(values))
    if len(values) < 2:
        return mean, math.nan
    return mean, float(t.ppf(0.975, len(values) - 1) * np.std(values, ddof=1) / math.sqrt(len(values)))


def summarize(rows: Sequence[dict]) -> list[dict]:
    """Per method and reference (in the rows' order): ``n`` sequences, ``ssim``/``mse`` means, ``*_ci`` half-widths."""
    keys = list(dict.fromkeys((r["method"], r["reference"]) for r in rows))
    out = []
    for method, ref in keys:
        mine = [r for r in rows if r["method"] == method and r["reference"] == ref]
        entry: dict = {"method": method, "reference": ref, "n": len(mine)}
        for metric in ("ssim", "mse"):
            entry[metric], entry[f"{metric}_ci"] = _interval(np.array([r[metric] for r in mine], np.float64))
        out.append(entry)
    return out


def paired_difference(rows: Sequence[dict], a: str, b: str, reference: str, metric: str = "ssim") -> dict:
    """Method ``a`` minus method ``b`` on the same sequences: the mean difference of ``metric`` with its 95 %
    Student-t half-width over sequences (tighter than comparing two means: the sequences' own difficulty
    cancels), and ``n``. Sequences scored by only one of them are left out."""
    by = {(r["file"], r["method"]): r[metric] for r in rows if r["reference"] == reference}
    files = [f for f in dict.fromkeys(r["file"] for r in rows) if (f, a) in by and (f, b) in by]
    diff, half = _interval(np.array([by[f, a] - by[f, b] for f in files], np.float64)) if files else (math.nan,) * 2
    return {"a": a, "b": b, "reference": reference, "metric": metric, "n": len(files), "difference": diff,
            "ci": half}


def table_markdown(summary: Sequence[dict]) -> str:
    """A markdown table: one line per method, MSE and SSIM (mean +- 95 % half-width) per reference."""
    refs = list(dict.fromkeys(s["reference"] for s in summary))
    methods = list(dict.fromkeys(s["method"] for s in summary))
    by = {(s["method"], s["reference"]): s for s in summary}
    head = "| method | " + " | ".join(f"MSE ({r}) | SSIM ({r})" for r in refs) + " |"
    lines = [head, "|" + " --- |" * (1 + 2 * len(refs))]

    def cell(s: dict | None, metric: str, digits: int) -> str:
        if s is None:
            return "-"
        ci = s[f"{metric}_ci"]
        return f"{s[metric]:.{digits}f}" + ("" if math.isnan(ci) else f" ± {ci:.{digits}f}")

    for m in methods:
        cells = [f"{cell(by.get((m, r)), 'mse', 4)} | {cell(by.get((m, r)), 'ssim', 3)}" for r in refs]
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    n = max((s["n"] for s in summary), default=0)
    return "\n".join(lines) + f"\n\nMean over {n} sequences ± the 95 % Student-t half-width over sequence means.\n"


def _plot(path: Path, summary: Sequence[dict], title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    refs = list(dict.fromkeys(s["reference"] for s in summary))
    methods = list(dict.fromkeys(s["method"] for s in summary))
    by = {(s["method"], s["reference"]): s for s in summary}
    fig, ax = plt.subplots(figsize=(1.1 * len(methods) + 2.5, 3.4), dpi=120)
    width = 0.8 / len(refs)
    for j, ref in enumerate(refs):
        x = np.arange(len(methods)) + (j - (len(refs) - 1) / 2) * width
        y = [by[m, ref]["ssim"] if (m, ref) in by else np.nan for m in methods]
        err = [by[m, ref]["ssim_ci"] if (m, ref) in by else np.nan for m in methods]
        ax.bar(x, y, width, yerr=np.nan_to_num(err), capsize=3, label=f"reference: {ref}")
    ax.set_xticks(np.arange(len(methods)), methods, rotation=30, ha="right")
    ax.set_ylabel("SSIM (mean over sequences, 95 % CI)")
    ax.set_ylim(0, 1)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def write_comparison(out: str | os.PathLike, rows: Sequence[dict], summary: Sequence[dict], *, title: str,
                     inputs: Sequence[Path], notes: str = "") -> None:
    """Write ``results.json`` (rows and summary), ``table.md`` (with ``notes`` after the table) and ``ssim.png``
    into the folder ``out`` (atomically; a reconstruction-kind output: only an earlier one is replaced)."""
    from gevsim.io import atomic_dir

    with atomic_dir(out, kind="reconstruction", inputs=list(inputs)) as stage:
        (stage / "results.json").write_text(json.dumps({"title": title, "summary": list(summary), "rows": list(rows)},
                                                       indent=1, default=float))
        (stage / "table.md").write_text(f"# {title}\n\n" + table_markdown(summary) + (f"\n{notes}\n" if notes else ""))
        _plot(stage / "ssim.png", summary, title)
