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

from gevsim.render.rays import image_points, primary_rays, sensor_grid
from gevsim.render.scene import MitsubaScene
from gevsim.render.trajectory import Pose

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


def _surface_points(scene: MitsubaScene, pose: Pose, unit: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World points (H*W, 3) seen through the pixel centres at ``pose``, whether each is a surface
    (H*W,), and the index of the moving object it lies on (-1: the static scene). ``unit`` (H*W, 3)
    are the rays' unit directions in float64: a point is the camera centre plus its direction times
    the hit distance (float32 in Mitsuba), so a point re-projected by the same camera lands on its
    pixel centre to float64 precision."""
    import drjit as dr
    import mitsuba as mi

    m = scene.manifest
    w, h = m.render.width, m.render.height
    scene.set_pose(pose)
    grid = sensor_grid(pose.camera, fov_deg=m.fov_deg, width=w, height=h)
    idx = dr.arange(mi.UInt32, w * h)
    centre = mi.Vector2f(mi.Float(idx % w), mi.Float(idx // w)) + 0.5
    near = float(scene.scene.sensors()[0].near_clip())
    ray = primary_rays(grid, centre, near_clip_m=near)
    si = scene.scene.ray_intersect(ray)
    owner = dr.full(mi.Int32, -1, w * h)
    shapes = {s.id(): s for s in scene.scene.shapes()}
    for i, motion in enumerate(m.motion):
        for obj in motion.objects:
            owner[si.shape == mi.ShapePtr(shapes[obj])] = i
    valid = np.array(si.is_valid(), dtype=bool).reshape(-1)
    forward = unit @ pose.camera[:3, 2]  # the z of each unit direction in the camera frame
    distance = np.where(valid, np.array(si.t, dtype=np.float64).reshape(-1), 0.0) + near / forward
    points = pose.camera[:3, 3] + unit * distance[:, None]
    return points, valid, np.array(owner, dtype=np.int64).reshape(-1)


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
    d_now = np.stack([(grid.cx - u) / grid.f_px, (grid.cy - v) / grid.f_px, np.ones_like(u)], -1)
    directions = (d_now @ now.camera[:3, :3].T).reshape(-1, 3)
    unit = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    points, valid, owner = _surface_points(scene, now, unit)
    moved = points.copy()
    for i, motion in enumerate(m.motion):
        on = valid & (owner == i)
        if on.any():
            a, b = now.objects[motion.objects[0]], later.objects[motion.objects[0]]
            step = b @ np.linalg.inv(a)
            moved[on] = points[on] @ step[:3, :3].T + step[:3, 3]
    seen = np.where(valid[:, None], moved - later.camera[:3, 3], directions)
    uv = image_points(later.camera, grid.f_px, grid.cx, grid.cy, seen).reshape(h, w, 2)
    flow = uv - np.stack([u, v], -1)
    depth = np.where(valid, (points - now.camera[:3, 3]) @ now.camera[:3, 2], 0.0).reshape(h, w)
    linear, angular = _velocities(scene, float(t_s))
    return FrameTruth(depth.astype(np.float32), np.nan_to_num(flow, nan=0.0).astype(np.float32), now.camera,
                      linear, angular)
