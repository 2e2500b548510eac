"""Ground truth written beside the events of a scene-mode run: log-photocurrent and APS frames,
and, at the same frame times, depth, forward optical flow and the camera's pose and velocities
(:mod:`gevsim.render.groundtruth`; layout in :mod:`gevsim.emulation.layout`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.constants import elementary_charge

from gevsim import _portable as pm
from gevsim.emulation import layout
from gevsim.emulation.photocurrent import photocurrent_at
from gevsim.illumination import weights_at

if TYPE_CHECKING:
    from gevsim.emulation.config import EmulationConfig
    from gevsim.emulation.photocurrent import Setup
    from gevsim.io import EventWriter
    from gevsim.pixel import ApsSensor
    from gevsim.render.scene import MitsubaScene


def write_frames(wr: EventWriter, setup: Setup, frame_t: np.ndarray, dark: Any, aps: ApsSensor | None,
                 aps_rng: np.random.Generator | None, config: EmulationConfig) -> None:
    """Ground truth: noise-free log photocurrent (with and without flicker), APS frames, and the
    scene's geometry at each frame time (when the setup holds its scene)."""
    mean = tuple(wf.constant() for wf in setup.waveforms)
    for t in frame_t:
        wt = weights_at(setup.waveforms, np.array([t]))
        wm = weights_at(mean, np.array([t]))
        t_us = int(round(t * 1e6))
        wr.append_frame(layout.LOG_PHOTOCURRENT, pm.log(photocurrent_at(setup, np.array([t]), wt)[0] + dark)
                        .astype(np.float32), t_us, **layout.FRAME_ATTRS[layout.LOG_PHOTOCURRENT])
        wr.append_frame(layout.LOG_PHOTOCURRENT_NO_FLICKER,
                        pm.log(photocurrent_at(setup, np.array([t]), wm)[0] + dark).astype(np.float32), t_us,
                        **layout.FRAME_ATTRS[layout.LOG_PHOTOCURRENT_NO_FLICKER])
        if aps is not None and aps_rng is not None and t >= config.aps_exposure_s:
            start = t - config.aps_exposure_s
            wa = weights_at(setup.waveforms, np.array([start]), average_over_s=config.aps_exposure_s)
            current = photocurrent_at(setup, np.array([start + 0.5 * config.aps_exposure_s]), wa)[0]
            electrons = current * config.aps_exposure_s / elementary_charge
            wr.append_frame(layout.APS, aps.read(electrons, config.aps_exposure_s, rng=aps_rng), t_us,
                            **layout.FRAME_ATTRS[layout.APS])
    if len(frame_t):
        wr.set_attrs("/frames", units="ln(A) for log_photocurrent*, DN for aps")
    if aps is not None and len(frame_t) > 1:
        p = aps.params
        wr.set_attrs(f"/frames/{layout.APS}", offset_dn=p.offset_dn, system_gain_dn_per_e=p.system_gain_dn_per_e,
                     bit_depth=p.bit_depth, exposure_s=config.aps_exposure_s)
    if setup.scene is not None and len(frame_t):
        write_geometry(wr, setup.scene, frame_t, 1.0 / config.frame_rate_hz)


def write_geometry(wr: EventWriter, scene: MitsubaScene, frame_t: np.ndarray, dt_s: float) -> None:
    """Depth and forward flow (to ``t + dt_s``, the next frame) as frame streams, and the camera's
    pose and velocities at each frame time under ``/poses``."""
    from gevsim.render.groundtruth import frame_truth

    cameras, linear, angular, t_us = [], [], [], []
    still = None if scene.manifest.moving else frame_truth(scene, 0.0, dt_s)  # nothing moves: one cast serves
    for t in frame_t:
        truth = still if still is not None else frame_truth(scene, float(t), dt_s)
        us = int(round(t * 1e6))
        wr.append_frame(layout.DEPTH, truth.depth_m, us, **layout.FRAME_ATTRS[layout.DEPTH])
        wr.append_frame(layout.FLOW, truth.flow_px, us, **layout.FRAME_ATTRS[layout.FLOW])
        cameras.append(truth.camera)
        linear.append(truth.linear_velocity_m_s)
        angular.append(truth.angular_velocity_rad_s)
        t_us.append(us)
    wr.set_attrs("/frames", units="ln(A) for log_photocurrent*, DN for aps, m for depth, px for flow")
    wr.write_array(layout.POSES_T, np.array(t_us, np.int64), units="us", meaning="time of each pose (the frames')")
    wr.write_array(layout.POSES_CAMERA, np.array(cameras), units="m",
                   meaning="camera-to-world 4x4 (columns: x left, y up, z forward in the image, centre), "
                           "Mitsuba's look_at axes")
    wr.write_array(layout.POSES_LINEAR, np.array(linear), units="m/s", meaning="camera velocity, world frame")
    wr.write_array(layout.POSES_ANGULAR, np.array(angular), units="rad/s",
                   meaning="camera angular velocity (axis times rate), world frame")
