"""The learned reconstruction network in PyTorch, for training (the ``learn`` extra), and :func:`export`, which
writes the weight file the numpy network (:class:`gevsim.learn.model.Model`) reads.

The same FireNet (Scheerlinck et al., WACV 2020) as :mod:`gevsim.learn.model`, layer for layer: the names
of its parameters are :func:`gevsim.learn.model.parameter_shapes`'s.
"""

from __future__ import annotations

import json
import os

import numpy as np
import torch
from torch import nn

from gevsim.io import atomic_path
from gevsim.learn.model import ARCHITECTURE, FORMAT, HIDDEN

__all__ = ["FireNet", "export"]


class ConvGRU(nn.Module):
    """A convolutional GRU cell (3x3 gates over [input, state])."""

    def __init__(self, hidden: int = HIDDEN):
        super().__init__()
        self.update = nn.Conv2d(2 * hidden, hidden, 3, padding=1)
        self.reset = nn.Conv2d(2 * hidden, hidden, 3, padding=1)
        self.out = nn.Conv2d(2 * hidden, hidden, 3, padding=1)

    def forward(self, x: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        stacked = torch.cat([x, state], dim=1)
        update = torch.sigmoid(self.update(stacked))
        reset = torch.sigmoid(self.reset(stacked))
        out = torch.tanh(self.out(torch.cat([x, state * reset], dim=1)))
        return state * (1 - update) + out * update


class Residual(nn.Module):
    """Two 3x3 convolutions, ReLU after the first and after adding the input."""

    def __init__(self, hidden: int = HIDDEN):
        super().__init__()
        self.conv1 = nn.Conv2d(hidden, hidden, 3, padding=1)
        self.conv2 = nn.Conv2d(hidden, hidden, 3, padding=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.conv2(torch.relu(self.conv1(x))) + x)


class FireNet(nn.Module):
    """The network over ``channels`` input channels; :meth:`forward` runs whole sequences."""

    def __init__(self, channels: int):
        super().__init__()
        self.channels = int(channels)
        self.head = nn.Conv2d(self.channels, HIDDEN, 3, padding=1)
        self.gru1, self.res1 = ConvGRU(), Residual()
        self.gru2, self.res2 = ConvGRU(), Residual()
        self.pred = nn.Conv2d(HIDDEN, 1, 1)

    def forward(self, inputs: torch.Tensor) -> torch.Tensor:
        """(B, T, C, H, W) -> (B, T, H, W) ln frames of zero mean, the state zero at t = 0."""
        b, t, _, h, w = inputs.shape
        s1 = inputs.new_zeros((b, HIDDEN, h, w))
        s2 = inputs.new_zeros((b, HIDDEN, h, w))
        frames = []
        for k in range(t):
            x = torch.relu(self.head(inputs[:, k]))
            s1 = self.gru1(x, s1)
            s2 = self.gru2(self.res1(s1), s2)
            frame = self.pred(self.res2(s2))[:, 0] + inputs[:, k, -1]  # corrects the classical channel
            frames.append(frame - frame.mean(dim=(1, 2), keepdim=True))
        return torch.stack(frames, dim=1)


def export(model: FireNet, path: str | os.PathLike, metadata: dict) -> None:
    """Write ``model``'s weights as float32 arrays named as in its state_dict, with ``metadata`` (JSON: at
    least ``encoding``; ``format``, ``architecture`` and ``input_channels`` are set here) to the .npz
    ``path``, atomically."""
    meta = {**metadata, "format": FORMAT, "architecture": ARCHITECTURE, "input_channels": model.channels}
    arrays = {k: v.detach().cpu().numpy().astype(np.float32) for k, v in model.state_dict().items()}
    with atomic_path(path, suffix=".npz") as tmp, open(tmp, "wb") as fh:
        np.savez(fh, metadata=np.str_(json.dumps(meta, sort_keys=True)), **arrays)
