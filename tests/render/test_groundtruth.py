"""Geometric ground truth: depth, flow and camera motion against analytic values, and the warp test."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gevsim.render import load
from gevsim.render.groundtruth import frame_truth
from gevsim.render.rays import focal_px
from gevsim.render.scene import MitsubaScene

DATA = Path(__file__).parents[1] / "data"
SCENES = Path(__file__).parents[2] / "scenes"


def card(tmp_path: Path, extra: str) -> MitsubaScene:
    """The test card (a fronto-parallel plane 3.5 m in front of the camera, filling the view) with ``extra``."""
    toml = tmp_path / "moving_card.toml"
    toml.write_text(f'[scene]\nextends = "{DATA / "card.toml"}"\nname = "moving_card"\n{extra}')
    return MitsubaScene(load(toml))


def test_depth_of_a_fronto_parallel_plane_is_its_distance(tmp_path):
    truth = frame_truth(card(tmp_path, ""), 0.0, 1e-3)
    assert truth.depth_m.shape == (24, 32)
    np.testing.assert_allclose(truth.depth_m, 3.5, rtol=1e-5)  # z-depth of a plane at z = 0, camera at z = 3.5
    assert np.abs(truth.flow_px).max() < 1e-9  # nothing moves
    assert np.all(truth.linear_velocity_m_s == 0) and np.all(truth.angular_velocity_rad_s == 0)


def test_flow_of_a_translating_camera_and_of_a_moving_object_is_f_d_over_z(tmp_path):
    f = focal_px(30.0, 32)
    # The camera moves 1 cm along world +x per ms (image-left is world -x here): the card slides left.
    camera = card(tmp_path, '[camera]\nkeyframes = [{ t_s = 0.0, origin = [0.0, 0.0, 3.5], target = [0.0, 0.0, 0.0] },'
                            ' { t_s = 0.004, origin = [0.04, 0.0, 3.5], target = [0.04, 0.0, 0.0] }]\n')
    truth = frame_truth(camera, 0.001, 1e-3)
    np.testing.assert_allclose(truth.flow_px[..., 0], -f * 0.01 / 3.5, rtol=1e-4)
    np.testing.assert_allclose(truth.flow_px[..., 1], 0.0, atol=1e-4)  # float32 hit points
    np.testing.assert_allclose(truth.linear_velocity_m_s, [10.0, 0.0, 0.0], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(truth.angular_velocity_rad_s, 0.0, atol=1e-6)
    # The card itself moves 1 cm along +x per ms: the same flow, the other way.
    obj = card(tmp_path, '[[motion]]\nobject = "card"\nkeyframes = [{ t_s = 0.0, translate_m = [0.0, 0.0, 0.0] }, '
                         '{ t_s = 0.004, translate_m = [0.04, 0.0, 0.0] }]\n')
    truth = frame_truth(obj, 0.001, 1e-3)
    np.testing.assert_allclose(truth.flow_px[..., 0], f * 0.01 / 3.5, rtol=1e-4)


def test_a_panning_camera_turns_at_the_rate_of_its_keyframes():
    m = load(SCENES / "office_pan.toml")
    scene = MitsubaScene(m)
    truth = frame_truth(scene, 0.01, 1e-3)
    a, b = (np.array(k.target) - np.array(k.origin) for k in m.camera)
    turn = math.acos(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b)) / 0.02  # rad/s, a uniform pan
    # Linear interpolation of the target is not a uniform rotation: within 1 % of the mean rate mid-pan.
    assert np.linalg.norm(truth.angular_velocity_rad_s) == pytest.approx(turn, rel=0.01)
    assert np.all(truth.depth_m > 0)  # the room encloses the camera
