"""Geometric ground truth at a frame time: depth, forward optical flow and the camera's motion.

What ESIM writes beside its events for learning depth, flow and ego-motion
(Rebecq et al., "ESIM: an open event camera simulator", CoRL 2018, sec. 4:
per-frame depth maps, optical flow, camera poses and velocities), computed here
from the scene itself rather than from a rendered image:

- one ray through each pixel centre (the sensor's own rays,
  :func:`gevsim.render.rays.primary_rays`) finds the surface point it sees;
- **depth** (m) is that point's z in the camera frame (along the optical axis,
  as ESIM's depth maps), 0 where the ray meets no surface;
- **forward flow** (px; x to the right, y down) is where that point is imaged
  ``dt_s`` later: a static point stays, a point of a moving object moves with its
  rigid transform (:func:`gevsim.render.trajectory.object_at`), the camera moves
  along its keyframes. A ray that meets nothing carries the flow of its direction
  (a point at infinity: only the camera's rotation moves it).
- the **camera pose** (4x4 camera-to-world, Mitsuba's ``look_at`` axes: x left,
  y up, z forward) and its **linear and angular velocity** in the world frame,
  by central differences of the trajectory over 1 us.

Flow is of the surface point at the pixel centre: a pixel that straddles an
edge averages two surfaces in the images but carries one flow here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gevsim.render.parallax import cast
from gevsim.render.rays import directions, image_points, sensor_grid
from gevsim.render.scene import MitsubaScene

#: Time step of the velocities' central differences (s).
VELOCITY_STEP_S = 1e-6


@dataclass(frozen=True)
class FrameTruth:
    """Ground truth at one time (see the module notes for conventions)."""

    depth_m: np.ndarray  # (H, W) float32, 0 where no surface
    flow_px: np.ndarray  # (H, W, 2) float32, forward flow (dx, dy) to t + dt_s
    camera: np.ndarray  # (4, 4) camera-to-world
    linear_velocity_m_s: np.ndarray  # (3,) world frame
    angular_velocity_rad_s: np.ndarray  # (3,) world frame (axis x rate)


def _velocities(scene: MitsubaScene, t_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(linear m/s, angular rad/s) of the camera at ``t_s``, world frame, central differences."""
    a, b = max(0.0, t_s - VELOCITY_STEP_S), t_s + VELOCITY_STEP_S
    ca, cb = scene.pose_at(a).camera, scene.pose_at(b).camera
    linear = (cb[:3, 3] - ca[:3, 3]) / (b - a)
    rel = cb[:3, :3] @ ca[:3, :3].T  # rotation from a to b, world frame
    angle = np.arccos(np.clip((np.trace(rel) - 1) / 2, -1.0, 1.0))
    axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
    norm = np.linalg.norm(axis)
    angular = axis / norm * angle / (b - a) if norm > 1e-15 else np.zeros(3)
    return linear, angular


def frame_truth(scene: MitsubaScene, t_s: float, dt_s: float) -> FrameTruth:
    """Depth, forward flow to ``t_s + dt_s``, pose and velocities at ``t_s`` (see the module notes)."""
    m = scene.manifest
    w, h = m.render.width, m.render.height
    now, later = scene.pose_at(float(t_s)), scene.pose_at(float(t_s + dt_s))
    grid = sensor_grid(now.camera, fov_deg=m.fov_deg, width=w, height=h)
    v, u = np.mgrid[0:h, 0:w].astype(float) + 0.5
    scene.set_pose(now)
    hits = cast(scene, now.camera, u, v)  # float64 points: a static one re-projects onto its pixel centre
    points, valid = hits.points, hits.valid
    motion_of = {obj: i for i, motion in enumerate(m.motion) for obj in motion.objects}
    owner = np.array([motion_of.get(s.id(), -1) for s in scene.scene.shapes()] + [-1])[hits.shape]  # -1: no hit
    moved = points.copy()
    for i, motion in enumerate(m.motion):
        on = valid & (owner == i)
        if on.any():
            a, b = now.objects[motion.objects[0]], later.objects[motion.objects[0]]
            step = b @ np.linalg.inv(a)
            moved[on] = points[on] @ step[:3, :3].T + step[:3, 3]
    rays = directions(now.camera, grid.f_px, grid.cx, grid.cy, u, v).reshape(-1, 3)
    seen = np.where(valid[:, None], moved - later.camera[:3, 3], rays)
    uv = image_points(later.camera, grid.f_px, grid.cx, grid.cy, seen).reshape(h, w, 2)
    flow = uv - np.stack([u, v], -1)
    depth = np.where(valid, (points - now.camera[:3, 3]) @ now.camera[:3, 2], 0.0).reshape(h, w)
    linear, angular = _velocities(scene, float(t_s))
    return FrameTruth(depth.astype(np.float32), np.nan_to_num(flow, nan=0.0).astype(np.float32), now.camera,
                      linear, angular)
