"""Gradient comparators' input offsets: a fixed pattern (Pelgrom offset of a differential pair)
that moves a comparator's +theta and -theta together. Implemented by
:class:`gevsim.events.gradient.GradientEmulator` (``offset_sigma_ln``)."""

from __future__ import annotations

from dataclasses import dataclass

from gevsim._validate import real


@dataclass(frozen=True)
class ComparatorOffset:
    """comparator_offset_v : sigma (volts) of the gradient comparators' input offsets."""

    comparator_offset_v: float = 0.0

    def __post_init__(self):
        real(self.comparator_offset_v, "comparator_offset_v", low=0)
