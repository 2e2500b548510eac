"""The emulation file beyond its event streams (DESIGN.md, Data contracts): ground-truth
frame names and what decoding and reconstruction start from. The driver and frame mode
write it through these names; the evaluation reads it through them.

::

    /frames/log_photocurrent             ln(A), as lit at each instant (scene mode)
    /frames/log_photocurrent_no_flicker  ln(A), every lamp at its mean (scene mode)
    /frames/aps                          DN, attrs offset_dn, system_gain_dn_per_e, ... (scene mode)
    /frames/intensity                    the input frames in [0, 1] (frame mode)
    /thresholds/<emulator>               gradient: theta (n, H, W); dvs: nominal (on, off) ln
    /initial_state/<emulator>            gradient: ternary state (2, H, W) before the first event
"""

from __future__ import annotations

import numpy as np

from gevsim.io import EventWriter

LOG_PHOTOCURRENT = "log_photocurrent"
LOG_PHOTOCURRENT_NO_FLICKER = "log_photocurrent_no_flicker"
APS = "aps"
INTENSITY = "intensity"


def thresholds_key(emulator: str) -> str:
    """Where an emulator's thresholds are stored."""
    return f"/thresholds/{emulator}"


def initial_state_key(emulator: str) -> str:
    """Where a gradient emulator's initial ternary state is stored."""
    return f"/initial_state/{emulator}"


def write_thresholds(writer: EventWriter, emulator: str, thresholds: np.ndarray) -> None:
    """Store an emulator's thresholds (gradient: theta as float32; dvs: nominal ON/OFF)."""
    writer.write_array(thresholds_key(emulator), thresholds)


def write_initial_state(writer: EventWriter, emulator: str, state: np.ndarray) -> None:
    """Store the ternary state decoding starts from."""
    writer.write_array(initial_state_key(emulator), state)
