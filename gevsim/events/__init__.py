"""Event emulators: brightness (DVS), gradient (Lehtonen et al.), center-surround."""

from gevsim.events.brightness import BrightnessEmulator, per_pixel_thresholds
from gevsim.events.center_surround import CenterSurroundEmulator
from gevsim.events.gradient import (
    LN_THRESHOLDS,
    PAPER_THRESHOLDS,
    GradientEmulator,
    decode,
    encode,
    gradients,
    ternary,
    threshold_matrix,
)
from gevsim.events.statistics import event_probability, event_rates
from gevsim.events.types import AXIS_X, AXIS_Y, BRIGHTNESS_DTYPE, GRADIENT_DTYPE, check_events, empty, is_gradient

__all__ = [
    "AXIS_X",
    "AXIS_Y",
    "BRIGHTNESS_DTYPE",
    "BrightnessEmulator",
    "CenterSurroundEmulator",
    "GRADIENT_DTYPE",
    "GradientEmulator",
    "LN_THRESHOLDS",
    "PAPER_THRESHOLDS",
    "decode",
    "event_probability",
    "event_rates",
    "encode",
    "gradients",
    "ternary",
    "threshold_matrix",
    "check_events",
    "empty",
    "is_gradient",
    "per_pixel_thresholds",
]
