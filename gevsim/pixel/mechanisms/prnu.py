"""Photo response non-uniformity: a per-pixel gain on the photocurrent (fixed pattern; EMVA 1288's
PRNU, relative sigma)."""

from __future__ import annotations

from dataclasses import dataclass

from gevsim._validate import real


@dataclass(frozen=True)
class Prnu:
    """prnu : relative sigma of the per-pixel photocurrent gain (at most 0.5)."""

    prnu: float = 0.0

    def __post_init__(self):
        real(self.prnu, "prnu", low=0, high=0.5)
