"""Training of the learned reconstruction (``gevsim train``; needs PyTorch, the ``learn`` extra).

The same for every encoding: Adam (lr 1e-3), truncated back-propagation through whole sequences (~10 frames),
mini-batches of random sequences in random crops and flips, and the L1 distance between the prediction and the
ground-truth ln frame, both of zero mean, over every frame but the first of each sequence (no history yet).
A held-back 10 % of the sequences gives the validation loss. Deterministic for a seed on one machine and thread
count (``torch.use_deterministic_algorithms``); the run stops after ``steps`` steps or ``minutes`` minutes.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from gevsim.io import atomic_path, atomic_write_text
from gevsim.learn.encode import ENCODINGS
from gevsim.learn.torch_model import FireNet, export
from gevsim.learn.train_data import Sequence_, batch

__all__ = ["TrainSettings", "TrainResult", "loss_of", "train", "write_outputs", "PLOT_MARK"]

#: What marks a loss-curve PNG as gevsim's (its Software text).
PLOT_MARK = "gevsim train"


@dataclass(frozen=True)
class TrainSettings:
    """Settings of one training run (units in the names)."""

    encoding: str
    seed: int = 0
    minutes: float = 10.0
    steps: int | None = None
    batch_size: int = 8
    crop_px: tuple[int, int] = (40, 48)  # (H, W)
    lr: float = 1e-3
    validation_fraction: float = 0.1
    eval_every: int = 50
    threads: int | None = None


@dataclass
class TrainResult:
    """A finished run: the model, its loss history and its cost."""

    model: FireNet
    steps: int = 0
    wall_s: float = 0.0
    train_loss: list[float] = field(default_factory=list)
    validation: list[tuple[int, float]] = field(default_factory=list)  # (step, loss)
    n_train: int = 0
    n_validation: int = 0


def loss_of(prediction: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """L1 between zero-mean prediction and zero-mean target (B, T, H, W), frames 1.. of each sequence."""
    zero = target - target.mean(dim=(2, 3), keepdim=True)
    pred = prediction - prediction.mean(dim=(2, 3), keepdim=True)
    return torch.mean(torch.abs(pred[:, 1:] - zero[:, 1:]))


def _split(n: int, fraction: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(train, validation) indices: a random ``fraction`` of n held back (at least one when n >= 2)."""
    order = rng.permutation(n)
    n_val = 0 if n < 2 else max(1, int(round(fraction * n)))
    return order[n_val:], order[:n_val]


def _validate(model: FireNet, sequences: Sequence[Sequence_]) -> float:
    if not sequences:
        return float("nan")
    with torch.no_grad():
        losses = [float(loss_of(model(torch.from_numpy(s.inputs)[None]), torch.from_numpy(s.targets)[None]))
                  for s in sequences]
    return float(np.mean(losses))


def train(sequences: Sequence[Sequence_], settings: TrainSettings, *,
          progress: Callable[[int, float, float], None] | None = None) -> TrainResult:
    """Train a fresh network on the encoded ``sequences``; ``progress(step, elapsed_s, loss)`` after each step."""
    if settings.encoding not in ENCODINGS:
        raise ValueError(f"unknown encoding {settings.encoding!r}; choose from {', '.join(ENCODINGS)}")
    if not sequences:
        raise ValueError("no sequences to train on")
    if settings.threads:
        torch.set_num_threads(int(settings.threads))
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(settings.seed)
    rng = np.random.default_rng(np.random.SeedSequence([settings.seed, 38]))
    train_idx, val_idx = _split(len(sequences), settings.validation_fraction, rng)
    train_set = [sequences[int(i)] for i in train_idx]
    val_set = [sequences[int(i)] for i in val_idx]
    model = FireNet(ENCODINGS[settings.encoding].channels)
    optimiser = torch.optim.Adam(model.parameters(), lr=settings.lr)
    result = TrainResult(model, n_train=len(train_set), n_validation=len(val_set))
    start = time.monotonic()
    budget_s = 60.0 * settings.minutes
    while (settings.steps is None or result.steps < settings.steps) and time.monotonic() - start < budget_s:
        x, y = batch(train_set, rng, size=settings.batch_size, crop=settings.crop_px)
        optimiser.zero_grad()
        loss = loss_of(model(torch.from_numpy(x)), torch.from_numpy(y))
        loss.backward()
        optimiser.step()
        result.steps += 1
        result.train_loss.append(loss.item())
        if result.steps % settings.eval_every == 0:
            result.validation.append((result.steps, _validate(model, val_set)))
        if progress:
            progress(result.steps, time.monotonic() - start, result.train_loss[-1])
    if not result.validation or result.validation[-1][0] != result.steps:
        result.validation.append((result.steps, _validate(model, val_set)))
    result.wall_s = time.monotonic() - start
    return result


def provenance(result: TrainResult, settings: TrainSettings, data: dict) -> dict:
    """The JSON beside the weights: what was trained on what, how long, on which machine."""
    import gevsim

    tail = result.train_loss[-min(len(result.train_loss), 50):]
    return {"format": "gevsim-training-provenance", "encoding": settings.encoding, "data": data,
            "gevsim_version": gevsim.__version__, "torch_version": torch.__version__, "seed": settings.seed,
            "steps": result.steps, "wall_s": round(result.wall_s, 1), "minutes_budget": settings.minutes,
            "steps_budget": settings.steps, "batch_size": settings.batch_size, "crop_px": list(settings.crop_px),
            "lr": settings.lr, "sequences": {"train": result.n_train, "validation": result.n_validation},
            "final_train_loss": float(np.mean(tail)) if tail else None,
            "final_validation_loss": _finite_or_none(result.validation[-1][1] if result.validation else None),
            "parameters": sum(p.numel() for p in result.model.parameters()),
            "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(),
                        "torch_threads": torch.get_num_threads()}}


def _finite_or_none(value: float | None) -> float | None:
    return value if value is not None and np.isfinite(value) else None  # JSON has no NaN


def write_outputs(result: TrainResult, settings: TrainSettings, out: str | os.PathLike, data: dict) -> dict:
    """Write the weights ``out`` (.npz), its provenance (``out`` with .json) and loss curve (with .png)."""
    out = Path(out)
    meta = provenance(result, settings, data)
    export(result.model, out, {"encoding": settings.encoding, "provenance": meta})
    meta = {**meta, "weights_sha256": hashlib.sha256(out.read_bytes()).hexdigest()}  # the JSON names its weights
    atomic_write_text(out.with_suffix(".json"), json.dumps(meta, indent=2, sort_keys=True) + "\n")
    _loss_plot(result, out.with_suffix(".png"), title=f"gevsim train --events {settings.encoding}")
    return meta


def _loss_plot(result: TrainResult, path: Path, *, title: str) -> None:
    from gevsim.plots import _pyplot

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    steps = np.arange(1, len(result.train_loss) + 1)
    ax.plot(steps, result.train_loss, lw=0.6, alpha=0.5, label="training (batch)")
    if len(steps) >= 20:
        k = max(len(steps) // 50, 5)
        smooth = np.convolve(result.train_loss, np.ones(k) / k, mode="valid")
        ax.plot(steps[k - 1:], smooth, lw=1.5, label=f"training ({k}-step mean)")
    val = [(s, v) for s, v in result.validation if np.isfinite(v)]
    if val:
        ax.plot(*zip(*val), "o-", label="validation (held back)")
    ax.set(xlabel="step", ylabel="L1 of zero-mean ln frames", title=title)
    ax.legend()
    fig.tight_layout()
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=100, format="png", metadata={"Software": PLOT_MARK})
    plt.close(fig)
