"""Camera and object trajectories, and the pose times at which to render.

Poses are rendered at a rate that keeps image motion under
``max_px_per_pose`` pixels between consecutive poses; irradiance between two
poses is the linear blend of their basis images (see
:func:`gevsim.illumination.mix_poses`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from gevsim.errors import ConfigError
from gevsim.render.manifest import CameraKey, Motion, SceneManifest

#: The most poses a scene may be rendered at (each is a render of every light group; at 1 s a render, a day).
MAX_POSES = 100_000


@dataclass(frozen=True)
class Pose:
    """Camera-to-world matrix and per-object rigid transforms at time ``t_s``."""

    t_s: float
    camera: np.ndarray  # 4x4 camera-to-world (Mitsuba look_at convention)
    objects: dict  # object id -> 4x4 world-space transform applied to its rest pose

    def key(self) -> dict:
        """The pose content that determines a render (for cache keys)."""
        return {
            "camera": np.round(self.camera, 9).tolist(),
            "objects": {k: np.round(v, 9).tolist() for k, v in sorted(self.objects.items())},
        }


def _interp(times, values, t):
    times = np.asarray(times, float)
    values = np.asarray(values, float)
    if len(times) == 1:
        return values[0]
    return np.array([np.interp(t, times, values[:, i]) for i in range(values.shape[1])])


def look_at(origin: ArrayLike, target: ArrayLike, up: ArrayLike) -> np.ndarray:
    """Mitsuba's ``look_at``: camera looks along +z towards ``target``, x = up x dir."""
    origin, target, up = (np.asarray(v, float) for v in (origin, target, up))
    direction = target - origin
    direction /= np.linalg.norm(direction)
    left = np.cross(up, direction)
    if np.linalg.norm(left) < 1e-12:
        raise ValueError(f"camera up vector {up.tolist()} is parallel to the view direction")
    left /= np.linalg.norm(left)
    new_up = np.cross(direction, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, direction, origin
    return m


def camera_at(keys: tuple[CameraKey, ...], t_s: float) -> np.ndarray:
    times = [k.t_s for k in keys]
    origin = _interp(times, [k.origin for k in keys], t_s)
    target = _interp(times, [k.target for k in keys], t_s)
    up = _interp(times, [k.up for k in keys], t_s)
    return look_at(origin, target, up)


def rotation(axis: ArrayLike, angle_rad: float) -> np.ndarray:
    """3x3 rotation by ``angle_rad`` about ``axis`` (Rodrigues)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle_rad) * k + (1 - math.cos(angle_rad)) * (k @ k)


def object_at(motion: Motion, centre: ArrayLike, t_s: float) -> np.ndarray:
    """World transform T(c + d(t)) R(axis, angle(t)) T(-c) for a rigid object with rest centre ``c``."""
    times = [k.t_s for k in motion.keyframes]
    translate = _interp(times, [k.translate_m for k in motion.keyframes], t_s)
    angle = float(_interp(times, [[k.rotate_deg] for k in motion.keyframes], t_s)[0])
    c = np.asarray(centre, float)
    m = np.eye(4)
    r = rotation(motion.axis, math.radians(angle))
    m[:3, :3] = r
    m[:3, 3] = c + translate - r @ c
    return m


def pose_at(manifest: SceneManifest, centres: dict, t_s: float) -> Pose:
    """The pose at time ``t_s`` (``centres[i]``: rest bounding-box centre of ``manifest.motion[i]``)."""
    objects = {}
    for i, m in enumerate(manifest.motion):
        mat = object_at(m, centres[i], t_s)
        objects.update({o: mat for o in m.objects})
    return Pose(t_s=float(t_s), camera=camera_at(manifest.camera, t_s), objects=objects)


def project(points: ArrayLike, camera: np.ndarray, *, fov_deg: float, width: int, height: int) -> np.ndarray:
    """Pixel coordinates of world ``points`` (N, 3) for a pinhole camera (NaN behind it)."""
    inv = np.linalg.inv(camera)
    xyz = np.asarray(points, float)
    p = np.c_[xyz, np.ones(len(xyz))] @ inv.T
    f_px = 0.5 * width / math.tan(math.radians(fov_deg) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(p[:, 2] > 1e-6, p[:, 2], np.nan)
        # Mitsuba's camera x axis points left in the image.
        u = width / 2 - f_px * p[:, 0] / z
        v = height / 2 - f_px * p[:, 1] / z
    return np.c_[u, v]


def pose_times(manifest: SceneManifest, probe_points: dict, centres: dict, *, samples: int = 400) -> np.ndarray:
    """Times of the poses to render, spaced so image motion stays under ``max_px_per_pose``.

    ``probe_points`` maps ``None`` to world points of the static scene (for
    camera motion) and each moving object's id to its rest-pose points. The
    image path length of every probe point is measured on a fine time grid,
    its maximum is split into steps of at most ``max_px_per_pose``.
    """
    if not manifest.moving:
        return np.array([0.0])
    r = manifest.render
    t = np.linspace(0.0, manifest.duration_s, samples + 1)
    tracks: list[np.ndarray] = []
    for ti in t:
        pose = pose_at(manifest, centres, ti)
        pts = [np.asarray(probe_points[None], float)]
        for obj, mat in pose.objects.items():
            rest = np.asarray(probe_points[obj], float)
            pts.append(np.c_[rest, np.ones(len(rest))] @ mat.T[:, :3])
        tracks.append(project(np.vstack(pts), pose.camera, fov_deg=manifest.fov_deg, width=r.width, height=r.height))
    track = np.array(tracks)  # (T, N, 2)
    step = np.linalg.norm(np.diff(track, axis=0), axis=2)
    # Ignore points outside a generous margin around the image (they do not show).
    inside = (np.abs(track[:-1, :, 0] - r.width / 2) < r.width) & (np.abs(track[:-1, :, 1] - r.height / 2) < r.height)
    step = np.where(inside & np.isfinite(step), step, 0.0)
    # Worst-case image motion per time step, accumulated: poses are placed at
    # equal increments of it, so fast and slow parts of a trajectory both stay
    # under the bound.
    cum = np.concatenate([[0.0], np.cumsum(step.max(axis=1))]) if step.size else np.zeros(len(t))
    poses = cum[-1] / r.max_px_per_pose
    if poses > MAX_POSES:
        raise ConfigError(f"max_px_per_pose = {r.max_px_per_pose:g} splits {cum[-1]:.4g} px of image motion into "
                          f"{poses:.4g} poses, each a render of every light group; at most {MAX_POSES} are allowed: "
                          "raise max_px_per_pose (1 px keeps motion smooth)", source=manifest.source,
                          key="render.max_px_per_pose")
    n = max(1, math.ceil(poses))
    if cum[-1] == 0:
        return np.linspace(0.0, manifest.duration_s, n + 1)
    return np.interp(np.linspace(0.0, cum[-1], n + 1), cum, t)
