"""Threshold mismatch: each comparator's ON and OFF thresholds differ from nominal by a Gaussian
fixed pattern (Lichtsteiner, Posch & Delbruck, JSSC 2008: 2.1 % contrast-threshold mismatch).
Implemented by the event emulators (:func:`gevsim.events.brightness.per_pixel_thresholds`, the
gradient emulator's ``mismatch_sigma_ln``)."""

from __future__ import annotations

from dataclasses import dataclass

from gevsim._validate import real


@dataclass(frozen=True)
class ThresholdMismatch:
    """threshold_mismatch_ln : per-comparator fixed-pattern sigma of the thresholds (ln units)."""

    threshold_mismatch_ln: float = 0.0

    def __post_init__(self):
        real(self.threshold_mismatch_ln, "threshold_mismatch_ln", low=0)
