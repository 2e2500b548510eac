"""The emulation file beyond its event streams (DESIGN.md, Data contracts): ground-truth
frame names and what decoding and reconstruction start from. The driver and frame mode
write it through these names; the evaluation reads it through them.

::

    /frames/log_photocurrent             ln(A), as lit at each instant (scene mode)
    /frames/log_photocurrent_no_flicker  ln(A), every lamp at its mean (scene mode)
    /frames/aps                          DN, attrs offset_dn, system_gain_dn_per_e, ... (scene mode)
    /frames/intensity                    the input frames in [0, 1] (frame mode)
    /frames/depth                        m, z in the camera frame at each pixel centre, 0: no surface (scene mode)
    /frames/flow                         px, (H, W, 2) forward optical flow to the next frame (scene mode)
    /poses/{t, camera_to_world, linear_velocity_m_s, angular_velocity_rad_s}   at the frame times (scene mode)
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
DEPTH = "depth"
FLOW = "flow"
POSES_T = "/poses/t"
POSES_CAMERA = "/poses/camera_to_world"
POSES_LINEAR = "/poses/linear_velocity_m_s"
POSES_ANGULAR = "/poses/angular_velocity_rad_s"

#: units and meaning of each frame stream's images (``EventWriter.append_frame(..., **FRAME_ATTRS[name])``).
FRAME_ATTRS: dict[str, dict[str, str]] = {
    LOG_PHOTOCURRENT: {"units": "ln(A)", "meaning": "noise-free log photocurrent (with dark current) as lit at "
                                                     "each instant: the ground truth"},
    LOG_PHOTOCURRENT_NO_FLICKER: {"units": "ln(A)", "meaning": "noise-free log photocurrent with every lamp at "
                                                                "its mean: the ground truth without flicker"},
    APS: {"units": "DN", "meaning": "APS frame (EMVA 1288 model) exposed until the frame time; "
                                    "see the group's offset_dn and system_gain_dn_per_e"},
    INTENSITY: {"units": "1", "meaning": "input frame, linear gray value in [0, 1] (frame mode)"},
    DEPTH: {"units": "m", "meaning": "depth (z in the camera frame) of the surface seen through each pixel centre; "
                                     "0 where there is none (gevsim.render.groundtruth)"},
    FLOW: {"units": "px", "meaning": "forward optical flow (dx right, dy down) of the surface point at each pixel "
                                     "centre, to the next frame's time (gevsim.render.groundtruth)"},
}


def thresholds_key(emulator: str) -> str:
    """Where an emulator's thresholds are stored."""
    return f"/thresholds/{emulator}"


def initial_state_key(emulator: str) -> str:
    """Where a gradient emulator's initial ternary state is stored."""
    return f"/initial_state/{emulator}"


def write_thresholds(writer: EventWriter, emulator: str, thresholds: np.ndarray, *, units: str = "ln") -> None:
    """Store an emulator's thresholds (gradient: theta (2, H, W) as float32; dvs: nominal ON/OFF), in
    ``units`` (ln units in scene mode, gray values in frame mode)."""
    thresholds = np.asarray(thresholds)
    if thresholds.ndim == 3:
        meaning = "threshold theta of each gradient comparator (axis 0 = X, 1 = Y; row; column)"
    else:
        meaning = "nominal (ON, OFF) contrast thresholds of the brightness events"
    writer.write_array(thresholds_key(emulator), thresholds, units=units, meaning=meaning)


def write_initial_state(writer: EventWriter, emulator: str, state: np.ndarray) -> None:
    """Store the ternary state decoding starts from."""
    writer.write_array(initial_state_key(emulator), state, units="1",
                       meaning="ternary gradient state (-1, 0, +1) of each comparator (axis, row, column) "
                               "before the first event: decoding starts from it")
