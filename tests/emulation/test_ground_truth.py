"""The geometric ground truth of a run (depth, flow, poses) and the warp test: flow carries frame k onto
frame k + 4 where the scene is seen in both."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.ndimage import map_coordinates

from gevsim.emulation.config import load_config
from gevsim.emulation.driver import run
from gevsim.emulation.layout import DEPTH, FLOW, LOG_PHOTOCURRENT_NO_FLICKER, POSES_CAMERA, POSES_T
from gevsim.io import EventReader

SCENES = Path(__file__).parents[2] / "scenes"


def warp_error(frames: np.ndarray, flow: np.ndarray, gap: int, scale: float) -> float:
    """Median |frame[k] - frame[k + gap] at x + scale * (flow[k] + ... + flow[k + gap - 1])| away from the border."""
    h, w = frames.shape[1:]
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    errors = []
    for k in range(len(frames) - gap):
        step = flow[k:k + gap].sum(axis=0)
        tx, ty = xx + scale * step[..., 0], yy + scale * step[..., 1]
        warped = map_coordinates(frames[k + gap], [ty, tx], order=3, mode="nearest")
        inside = (tx > 2) & (tx < w - 3) & (ty > 2) & (ty < h - 3)
        errors.append(np.abs(warped - frames[k])[inside])
    return float(np.median(np.concatenate(errors)))


def test_a_panning_camera_writes_depth_flow_and_poses_and_flow_warps_the_frames(tmp_path):
    cfg = tmp_path / "pan.toml"
    cfg.write_text(f'[emulation]\nscene = "{SCENES / "office_pan.toml"}"\nsensor = "ideal"\nemulators = ["dvs"]\n'
                   'step_s = 1e-4\nframe_rate_hz = 500.0\n[render]\nwidth = 48\nheight = 36\nspp = 64\n')
    run(load_config(cfg), tmp_path / "pan.h5", cache_dir=tmp_path / "cache")
    with EventReader(tmp_path / "pan.h5") as r:
        frames, t_us = r.frames(LOG_PHOTOCURRENT_NO_FLICKER)
        depth, depth_t = r.frames(DEPTH)
        flow, _ = r.frames(FLOW)
        cameras, pose_t = r.array(POSES_CAMERA), r.array(POSES_T)
    assert len(frames) == 11 and flow.shape == (11, 36, 48, 2) and cameras.shape == (11, 4, 4)
    np.testing.assert_array_equal(depth_t, t_us)
    np.testing.assert_array_equal(pose_t, t_us)
    assert (depth > 0.5).all() and (depth < 6).all()  # inside the office
    # Flow is right in direction and size: the warp error is smallest at scale 1 and far below no warp.
    errors = {s: warp_error(frames, flow, 4, s) for s in (0.0, 0.8, 1.0, 1.2)}
    assert errors[1.0] < 0.5 * errors[0.0], errors
    assert errors[1.0] < min(errors[0.8], errors[1.2]), errors
