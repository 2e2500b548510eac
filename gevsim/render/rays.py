"""Pinhole image planes as numbers: pixel grids, their rays, and the map between rotated views.

Mitsuba's ``perspective`` sensor (``fov_axis = "x"``) images the camera-space
direction ``(x, y, z)`` at image coordinates ``u = cx - f x / z``,
``v = cy - f y / z`` (pixels; ``f = W / (2 tan(fov / 2))``, ``(cx, cy)`` the
image centre, camera x pointing left in the image), and starts its rays on the
near-clip plane. A :class:`PinholeGrid` is any axis-aligned window of that
image plane, at any number of sub-pixels per pixel: the sensor's own film is
one (:func:`sensor_grid`), a wider window seen by the same camera is another.

Two cameras at one centre see the same radiance along each direction, so a
pixel of one view is a region of the other's image plane (:func:`map_view`):
a pure rotation is an exact resampling (:mod:`gevsim.render.rotation`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Mitsuba's ``perspective`` default near clip (m): its rays start this far along z.
NEAR_CLIP_M = 0.01


def focal_px(fov_deg: float, width: int) -> float:
    """Focal length in pixels of a pinhole with horizontal field of view ``fov_deg`` over ``width`` px."""
    return 0.5 * width / math.tan(math.radians(fov_deg) / 2)


@dataclass(frozen=True)
class PinholeGrid:
    """A window of a pinhole camera's image plane, cut into ``sub`` x ``sub`` cells per pixel.

    Attributes
    ----------
    camera : 4x4 camera-to-world matrix (Mitsuba's ``look_at`` convention).
    f_px, cx, cy : focal length and image centre, in pixels of the camera's image.
    u0, v0 : image coordinates (pixels) of the window's top-left corner.
    width, height : the window's size in cells.
    sub : cells per pixel along each axis.
    """

    camera: np.ndarray
    f_px: float
    cx: float
    cy: float
    u0: float
    v0: float
    width: int
    height: int
    sub: int = 1

    def key(self) -> dict:
        """What fixes the grid's rays (for cache keys)."""
        return {"camera": np.round(self.camera, 9).tolist(),
                "plane": [round(float(v), 9) for v in (self.f_px, self.cx, self.cy, self.u0, self.v0)],
                "size": [int(self.width), int(self.height), int(self.sub)]}


def sensor_grid(camera: np.ndarray, *, fov_deg: float, width: int, height: int) -> PinholeGrid:
    """The grid of a ``width`` x ``height`` film seen through ``camera``: the sensor's own pixels."""
    return PinholeGrid(np.asarray(camera, float), focal_px(fov_deg, width), width / 2, height / 2, 0.0, 0.0,
                       int(width), int(height), 1)


def directions(camera: np.ndarray, f_px: float, cx: float, cy: float, u: Any, v: Any) -> np.ndarray:
    """World directions (..., 3), not normalised, through image points ``(u, v)`` of ``camera``."""
    u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
    d = np.stack([(cx - u) / f_px, (cy - v) / f_px, np.ones_like(u)], axis=-1)
    return d @ np.asarray(camera, float)[:3, :3].T


def image_points(camera: np.ndarray, f_px: float, cx: float, cy: float, d_world: np.ndarray) -> np.ndarray:
    """Image coordinates (..., 2) of world directions in ``camera`` (NaN where a direction is not in front)."""
    d = np.asarray(d_world, float) @ np.asarray(camera, float)[:3, :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(d[..., 2] > 1e-9, d[..., 2], np.nan)
        return np.stack([cx - f_px * d[..., 0] / z, cy - f_px * d[..., 1] / z], axis=-1)


def map_view(grid: PinholeGrid, camera: np.ndarray, *, width: int, height: int) -> np.ndarray:
    """Where the pixel corners of a ``width`` x ``height`` view through ``camera`` (same centre, same
    focal length and image centre as ``grid``) fall on ``grid``: (height + 1, width + 1, 2) cell coordinates
    (x, y), NaN where a corner looks away from the grid's camera."""
    v, u = np.mgrid[0:height + 1, 0:width + 1].astype(float)
    d = directions(camera, grid.f_px, width / 2, height / 2, u, v)
    uv = image_points(grid.camera, grid.f_px, grid.cx, grid.cy, d)
    return np.stack([(uv[..., 0] - grid.u0) * grid.sub, (uv[..., 1] - grid.v0) * grid.sub], axis=-1)


def primary_rays(grid: PinholeGrid, position: Any, *, near_clip_m: float = NEAR_CLIP_M) -> Any:
    """``mitsuba.Ray3f`` through cell coordinates ``position`` (a ``mitsuba.Vector2f``, cells from the
    window's corner), started on the near-clip plane as Mitsuba's ``perspective`` sensor does."""
    import drjit as dr
    import mitsuba as mi

    m = np.asarray(grid.camera, float)

    def c(x: float) -> Any:  # a kernel input, not a literal: one compiled kernel serves every pose and window
        return dr.opaque(mi.Float, float(x))

    u = c(grid.u0) + position.x / float(grid.sub)
    v = c(grid.v0) + position.y / float(grid.sub)
    f = c(grid.f_px)
    local = dr.normalize(mi.Vector3f((c(grid.cx) - u) / f, (c(grid.cy) - v) / f, 1.0))
    rows = [[c(m[i, j]) for j in range(3)] for i in range(3)]
    world = mi.Vector3f(*(rows[i][0] * local.x + rows[i][1] * local.y + rows[i][2] * local.z for i in range(3)))
    near_t = c(near_clip_m) / local.z
    origin = mi.Point3f(*(c(m[i, 3]) + world[i] * near_t for i in range(3)))
    return mi.Ray3f(origin, world)
