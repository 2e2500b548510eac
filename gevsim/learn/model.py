"""The learned reconstruction network in numpy (inference only: the shipped weights run without PyTorch).

The network is FireNet (Scheerlinck, Rebecq, Gehrig, Barnes, Mahony & Scaramuzza, "Fast image
reconstruction with an event camera", WACV 2020, Fig. 2), written here from the paper's description: a
3x3 head convolution (C -> 16) with ReLU, a 3x3 ConvGRU (16), a residual block (two 3x3 convolutions of
16 channels with ReLU, the input added before the second ReLU), a second ConvGRU and residual block, and a
1x1 prediction convolution (16 -> 1); ~38 k parameters. It is recurrent over the frames of one sequence
(state zero at the start). Unlike FireNet it predicts the ln frame with zero mean (no sigmoid: the
evaluation sets the level), and it predicts a *correction*: the output is the input's last channel (the
classical reconstruction from the same events, :mod:`gevsim.learn.encode`) plus the prediction. An untrained
network is thus near the classical method, and a CPU-sized training budget goes into what it gets wrong
(a residual, as in ResNet: He et al., CVPR 2016) rather than into learning to copy it. Its PyTorch twin, for
training, is :mod:`gevsim.learn.torch_model`.

Convolutions use zero padding, computed as im2col + one matrix product per layer (float32 values, summed
in float64 in a fixed order: the same bits on every CPU).
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import numpy as np

from gevsim import _portable as pm
from gevsim.errors import ConfigError

__all__ = ["ARCHITECTURE", "FORMAT", "HIDDEN", "Model", "is_model_file", "parameter_count", "parameter_shapes"]

#: The architecture version stored in a weight file; a file of another version is refused.
ARCHITECTURE = "firenet-residual-1"
#: The ``format`` entry of a weight file's metadata: what marks a file as written by gevsim.
FORMAT = "gevsim-learned-reconstruction"
#: Channels of the hidden layers (FireNet: 16).
HIDDEN = 16


def parameter_shapes(channels: int) -> dict[str, tuple[int, ...]]:
    """Every weight's name (PyTorch's state_dict names) and shape for ``channels`` input channels."""
    h = HIDDEN
    shapes: dict[str, tuple[int, ...]] = {"head.weight": (h, channels, 3, 3), "head.bias": (h,)}
    for k in (1, 2):
        for gate in ("update", "reset", "out"):
            shapes[f"gru{k}.{gate}.weight"] = (h, 2 * h, 3, 3)
            shapes[f"gru{k}.{gate}.bias"] = (h,)
        for conv in ("conv1", "conv2"):
            shapes[f"res{k}.{conv}.weight"] = (h, h, 3, 3)
            shapes[f"res{k}.{conv}.bias"] = (h,)
    shapes["pred.weight"] = (1, h, 1, 1)
    shapes["pred.bias"] = (1,)
    return shapes


def parameter_count(channels: int) -> int:
    """The number of parameters of the network with ``channels`` input channels."""
    return sum(int(np.prod(s)) for s in parameter_shapes(channels).values())


class _Im2col:
    """(C, H, W) -> (C * 9, H * W): the 3x3 neighbourhoods, zero padded, rows ordered (c, ky, kx) as a
    PyTorch weight (Cout, C, 3, 3) reshaped to (Cout, C * 9). Its buffers are kept per shape and reused
    (allocating ~100 MB per layer at 346x260 took as long as the copies); a result is valid until the next
    call with the same channel count."""

    def __init__(self) -> None:
        self.buffers: dict[tuple[int, int, int], tuple[np.ndarray, np.ndarray]] = {}

    def __call__(self, x: np.ndarray) -> np.ndarray:
        c, h, w = x.shape
        if (c, h, w) not in self.buffers:
            self.buffers[(c, h, w)] = np.zeros((c, h + 2, w + 2), np.float32), np.empty((c, 9, h, w), np.float32)
        pad, cols = self.buffers[(c, h, w)]
        pad[:, 1:-1, 1:-1] = x
        for ky in range(3):
            for kx in range(3):
                cols[:, 3 * ky + kx] = pad[:, ky:ky + h, kx:kx + w]
        return cols.reshape(c * 9, h * w)


def _matmul(w: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``w @ cols`` summed in float64 in a fixed order, rounded to float32: the same bits on every CPU (a BLAS
    product, ~4x faster, picks its kernel, and so its last bits, by the CPU: tests/test_architecture.py)."""
    return pm.weighted_sum(w, cols, dtype=np.float32)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return (1.0 / (1.0 + pm.exp(-x))).astype(np.float32)


def _tanh(x: np.ndarray) -> np.ndarray:
    return (1.0 - 2.0 / (pm.exp(2.0 * x) + 1.0)).astype(np.float32)  # exp overflows to inf: tanh = 1


class Model:
    """The network with its weights: ``Model(weights, metadata)`` or :meth:`load`; :meth:`run` reconstructs.

    ``metadata`` holds at least ``encoding`` and ``input_channels``; ``source`` names the weights in errors.
    """

    def __init__(self, weights: dict[str, np.ndarray], metadata: dict, *, source: str | None = None):
        self.metadata = dict(metadata)
        self.source = source
        channels = self.metadata.get("input_channels")
        if self.metadata.get("architecture") != ARCHITECTURE or not isinstance(channels, int) or channels < 1:
            raise ConfigError(f"weights of architecture {self.metadata.get('architecture')!r} with "
                              f"{channels!r} input channels; this gevsim reads {ARCHITECTURE!r}", source=source)
        self.channels, self.encoding = channels, str(self.metadata.get("encoding"))
        shapes = parameter_shapes(channels)
        if set(weights) != set(shapes):
            odd = sorted(set(weights) ^ set(shapes))
            raise ConfigError(f"weights do not match {ARCHITECTURE}: {', '.join(odd[:3])} missing or unexpected",
                              source=source)
        self.weights: dict[str, np.ndarray] = {}
        self._im2col = _Im2col()
        for name, shape in shapes.items():
            a = np.asarray(weights[name])
            if a.shape != shape or a.dtype.kind != "f" or not np.all(np.isfinite(a)):
                raise ConfigError(f"corrupt weight {name}: expected {shape} finite floats, got {a.shape} of "
                                  f"{a.dtype}", source=source)
            a = a.astype(np.float32)
            self.weights[name] = a.reshape(shape[0], -1) if a.ndim == 4 else a  # (Cout, Cin * k * k)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Model:
        """Read a weight file (.npz of named arrays and a JSON ``metadata`` entry) that
        :func:`gevsim.learn.torch_model.export` wrote; ConfigError naming the file otherwise."""
        source = str(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise ConfigError("no such weight file", source=source) from None
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise ConfigError(f"not a weight file (.npz): {exc}", source=source) from None
        meta = arrays.pop("metadata", None)
        try:
            metadata = json.loads(str(meta[()])) if meta is not None and meta.dtype.kind == "U" else None
        except (ValueError, IndexError):
            metadata = None
        if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
            raise ConfigError(f"not a gevsim weight file: no JSON metadata of format {FORMAT!r}", source=source)
        return cls(arrays, metadata, source=source)

    def _conv3(self, name: str, cols: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        out = _matmul(self.weights[f"{name}.weight"], cols)
        out += self.weights[f"{name}.bias"][:, None]
        return out.reshape((-1,) + shape)

    def _gru(self, name: str, x: np.ndarray, state: np.ndarray) -> np.ndarray:
        shape = x.shape[1:]
        cols = self._im2col(np.concatenate([x, state]))
        update = _sigmoid(self._conv3(f"{name}.update", cols, shape))
        reset = _sigmoid(self._conv3(f"{name}.reset", cols, shape))
        w = self.weights[f"{name}.out.weight"]
        n = HIDDEN * 9  # the out gate sees [x, reset * state]: x's columns are those above
        out = _matmul(w[:, :n], cols[:n]) + _matmul(w[:, n:], self._im2col(state * reset))
        out += self.weights[f"{name}.out.bias"][:, None]
        return state * (1 - update) + _tanh(out.reshape(x.shape)) * update

    def _residual(self, name: str, x: np.ndarray) -> np.ndarray:
        shape = x.shape[1:]
        y = np.maximum(self._conv3(f"{name}.conv1", self._im2col(x), shape), 0)
        return np.maximum(self._conv3(f"{name}.conv2", self._im2col(y), shape) + x, 0)

    def run(self, inputs: np.ndarray) -> np.ndarray:
        """Reconstruct the ln frames (M, H, W) float64, each of zero mean, from the encoded inputs
        (M, C, H, W) of one sequence (:func:`gevsim.learn.encode.encode`), the recurrent state zero at the
        first frame."""
        x = np.asarray(inputs)
        if x.ndim != 4 or x.shape[1] != self.channels:
            raise ValueError(f"inputs must be (M, {self.channels}, H, W) for the {self.encoding!r} weights, "
                             f"got shape {x.shape}")
        m, _, h, w = x.shape
        out = np.empty((m, h, w), np.float64)
        states = [np.zeros((HIDDEN, h, w), np.float32) for _ in range(2)]
        for k in range(m):
            f = np.maximum(self._conv3("head", self._im2col(np.asarray(x[k], np.float32)), (h, w)), 0)
            states[0] = self._gru("gru1", f, states[0])
            f = self._residual("res1", states[0])
            states[1] = self._gru("gru2", f, states[1])
            f = self._residual("res2", states[1])
            pred = _matmul(self.weights["pred.weight"], f.reshape(HIDDEN, -1)) + self.weights["pred.bias"][:, None]
            frame = pred.reshape(h, w).astype(np.float64) + x[k, -1]  # the correction of the classical channel
            out[k] = frame - frame.mean()
        self._im2col.buffers.clear()  # ~150 MB at 346x260: not kept between sequences
        return out


def is_model_file(path: Path) -> bool:
    """Whether ``path`` is a weight file gevsim wrote (the kind ``gevsim train --out`` may replace)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if "metadata" not in z.files:
                return False
            return json.loads(str(z["metadata"][()])).get("format") == FORMAT
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, AttributeError):
        return False
