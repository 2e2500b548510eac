"""A static scene seen from a moving camera: converged radiance reprojected through the scene's geometry.

Where every surface reflects diffusely and every emitter is a diffuse area
light, the radiance leaving a surface point does not depend on the direction it
is seen from. A pixel of pose p then sees the same radiance as the region of a
reference render onto which its footprint's surface projects. For each pixel of
pose p the rays through its four corners and its centre find the surface
(:func:`cast`); the pixel is *reused* when

- all five hit one shape, with geometric normals within :data:`MAX_NORMAL_DEG`
  (one flat piece of surface, no edge or crease inside the pixel);
- all five points are seen from the reference camera's centre (nothing in
  front of them there: no disocclusion);
- their projections onto the reference image plane lie within
  :data:`MAX_SHEAR_PX` of the axis-aligned rectangle through the mapped edge
  midpoints, and inside the reference window.

A reused pixel is the exact box integral of the reference cells over that
rectangle (:func:`gevsim.render.rotation.box_resample`); every other pixel is
rendered anew at pose p (:func:`gevsim.render.poses.render_parallax`). The
approximations are those of rotation reuse, plus the rectangle standing for a
footprint that perspective makes a general quadrilateral (bounded by
:data:`MAX_SHEAR_PX`), and a surface's radiance being taken as constant across
the pixel's footprint (what a box filter does anyway).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gevsim.render.rays import PinholeGrid, directions, focal_px, image_points, primary_rays, sensor_grid
from gevsim.render.rotation import Segment, edge_rect
from gevsim.render.scene import MitsubaScene

#: Largest angle (deg) between the normals at a pixel's corners and centre for it to be one flat surface.
MAX_NORMAL_DEG = 2.0
#: Largest distance (px) of a mapped footprint corner from its rectangle for the pixel to be reused.
MAX_SHEAR_PX = 0.25
#: Relative tolerance of the visibility test (a point counts as seen if nothing is hit before this share of it).
VISIBLE_REL = 1e-4


@dataclass(frozen=True)
class Hits:
    """Surface points seen through image points: world points (N, 3) float64, whether each is a surface,
    the index of the shape hit (-1: none) and its geometric normal (N, 3)."""

    points: np.ndarray
    valid: np.ndarray
    shape: np.ndarray
    normal: np.ndarray


def view_independent(scene: MitsubaScene) -> str | None:
    """Why the radiance leaving the scene's surfaces depends on the view (None when it does not)."""
    import mitsuba as mi

    for shape in scene.scene.shapes():
        bsdf = shape.bsdf()
        flags = int(bsdf.flags()) if bsdf is not None else 0
        if flags & int(mi.BSDFFlags.Glossy | mi.BSDFFlags.Delta):
            return f"shape {shape.id()!r} is not diffuse (its radiance depends on the view)"
    for emitter in scene.scene.emitters():
        if not mi.has_flag(emitter.flags(), mi.EmitterFlags.Surface):
            return f"emitter {emitter.id()!r} is not an area light"
    return None


def cast(scene: MitsubaScene, camera: np.ndarray, u: np.ndarray, v: np.ndarray) -> Hits:
    """What the rays of ``camera`` (the scene's lens and film) through image points (u, v) hit."""
    import drjit as dr
    import mitsuba as mi

    m = scene.manifest
    grid = sensor_grid(camera, fov_deg=m.fov_deg, width=m.render.width, height=m.render.height)
    u, v = np.asarray(u, float).ravel(), np.asarray(v, float).ravel()
    near = float(scene.scene.sensors()[0].near_clip())
    ray = primary_rays(grid, mi.Vector2f(mi.Float(u), mi.Float(v)), near_clip_m=near)
    si = scene.scene.ray_intersect(ray)
    valid = np.array(si.is_valid(), dtype=bool).reshape(-1)
    d = directions(camera, grid.f_px, grid.cx, grid.cy, u, v)
    d /= np.linalg.norm(d, axis=1, keepdims=True)  # float64: a point re-projects onto its image point exactly
    distance = np.where(valid, np.array(si.t, dtype=np.float64).reshape(-1), 0.0) + near / (d @ camera[:3, 2])
    # The shape hit, as its index in scene.shapes(): Mitsuba's registry id of each shape, looked up.
    ids = np.array([int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]) for s in scene.scene.shapes()])
    lookup = np.full(int(ids.max(initial=0)) + 1, -1, np.int64)
    lookup[ids] = np.arange(len(ids))
    hit = np.array(dr.reinterpret_array(mi.UInt32, si.shape), dtype=np.int64).reshape(-1)
    owner = np.where(valid & (hit < len(lookup)), lookup[np.minimum(hit, len(lookup) - 1)], -1)
    normal = np.array(si.n, dtype=np.float64).reshape(3, -1).T if len(u) > 1 else np.array(si.n).reshape(1, 3)
    return Hits(camera[:3, 3] + d * distance[:, None], valid, owner, normal)


def visible_from(scene: MitsubaScene, points: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Whether each world point is seen from ``centre`` (no surface strictly between them)."""
    import mitsuba as mi

    d = points - centre
    dist = np.linalg.norm(d, axis=1)
    dist = np.where(dist > 0, dist, 1.0)
    unit = d / dist[:, None]
    o = mi.Point3f(*(mi.Float(np.full(len(points), float(c))) for c in centre))
    ray = mi.Ray3f(o, mi.Vector3f(*(mi.Float(unit[:, i]) for i in range(3))))
    ray.maxt = mi.Float(dist * (1 - VISIBLE_REL))
    return ~np.array(scene.scene.ray_test(ray), dtype=bool).reshape(-1)


def window(scene: MitsubaScene, cameras: list[np.ndarray], ref: np.ndarray, *, margin_px: int = 2,
           border_step: int = 4) -> tuple[float, float, float, float] | None:
    """(u_min, v_min, u_max, v_max) on ``ref``'s image plane covering what the cameras' image borders see
    (sampled every ``border_step`` px), or None where a seen point is behind the reference camera."""
    m = scene.manifest
    w, h = m.render.width, m.render.height
    f = focal_px(m.fov_deg, w)
    xs, ys = np.r_[np.arange(0, w, border_step), w], np.r_[np.arange(0, h, border_step), h]
    u = np.r_[xs, xs, np.zeros_like(ys), np.full_like(ys, w)].astype(float)
    v = np.r_[np.zeros_like(xs), np.full_like(xs, h), ys, ys].astype(float)
    boxes = []
    for cam in cameras:
        hits = cast(scene, cam, u, v)
        seen = np.where(hits.valid[:, None], hits.points - ref[:3, 3],
                        (hits.points - cam[:3, 3]))  # a miss: its direction
        uv = image_points(ref, f, w / 2, h / 2, seen)
        if not np.isfinite(uv).all():
            return None
        boxes.append(np.r_[uv.min(axis=0), uv.max(axis=0)])
    b = np.array(boxes)
    return (math.floor(b[:, 0].min()) - margin_px, math.floor(b[:, 1].min()) - margin_px,
            math.ceil(b[:, 2].max()) + margin_px, math.ceil(b[:, 3].max()) + margin_px)


def reproject(scene: MitsubaScene, grid: PinholeGrid, camera: np.ndarray, *,
              sub: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(rect, ok)``: the footprint on ``grid`` of each of the ``sub`` x ``sub`` cells of each pixel of
    the view through ``camera`` (4, H sub, W sub; in grid cells, as :func:`gevsim.render.rotation.footprints`)
    and whether it may be reused (see the module notes; the tests are applied to each cell)."""
    m = scene.manifest
    w, h = m.render.width * sub, m.render.height * sub
    vc, uc = np.mgrid[0:h + 1, 0:w + 1].astype(float) / sub
    n_corners = uc.size  # corners and centres in one cast and one visibility test
    both = cast(scene, camera, np.r_[uc.ravel(), (uc[:-1, :-1] + 0.5 / sub).ravel()],
                np.r_[vc.ravel(), (vc[:-1, :-1] + 0.5 / sub).ravel()])
    corners, centres = (Hits(both.points[part], both.valid[part], both.shape[part], both.normal[part])
                        for part in (slice(None, n_corners), slice(n_corners, None)))
    ref_centre = grid.camera[:3, 3]
    seen_all = visible_from(scene, both.points, ref_centre) & both.valid

    def cells(hits: Hits, shape: tuple[int, int]) -> np.ndarray:
        uv = image_points(grid.camera, grid.f_px, grid.cx, grid.cy, hits.points - ref_centre)
        return ((uv - [grid.u0, grid.v0]) * grid.sub).reshape(*shape, 2)

    c, mid = cells(corners, (h + 1, w + 1)), cells(centres, (h, w))
    rect = edge_rect(c)
    x0, y0, x1, y1 = rect

    def at_corners(a: np.ndarray) -> list[np.ndarray]:
        a = a.reshape(h + 1, w + 1, *a.shape[1:])
        return [a[:-1, :-1], a[:-1, 1:], a[1:, :-1], a[1:, 1:]]

    seen, seen_mid = seen_all[:n_corners], seen_all[n_corners:]
    shape_mid, normal_mid = centres.shape.reshape(h, w), centres.normal.reshape(h, w, 3)
    cos_max = math.cos(math.radians(MAX_NORMAL_DEG))
    ok = seen_mid.reshape(h, w).copy()
    for s, sh, n in zip(at_corners(seen), at_corners(corners.shape), at_corners(corners.normal)):
        ok &= s & (sh == shape_mid) & (np.einsum("...i,...i", n, normal_mid) >= cos_max)
    # The footprint is near its rectangle: corners within MAX_SHEAR_PX of its sides, centre near its centre.
    tol = MAX_SHEAR_PX * grid.sub / sub
    with np.errstate(invalid="ignore"):
        off = np.maximum.reduce([np.abs(c[:-1, :-1, 0] - c[1:, :-1, 0]), np.abs(c[:-1, 1:, 0] - c[1:, 1:, 0]),
                                 np.abs(c[:-1, :-1, 1] - c[:-1, 1:, 1]), np.abs(c[1:, :-1, 1] - c[1:, 1:, 1]),
                                 2 * np.abs(mid[..., 0] - 0.5 * (x0 + x1)), 2 * np.abs(mid[..., 1] - 0.5 * (y0 + y1))])
        ok &= np.isfinite(rect).all(axis=0) & (off <= 2 * tol) & (x1 > x0) & (y1 > y0)
        ok &= (x0 >= 0) & (y0 >= 0) & (x1 <= grid.width) & (y1 <= grid.height)
    rect = np.where(ok[None], rect, np.array([0.0, 0.0, 1.0, 1.0])[:, None, None])  # failed pixels: a harmless box
    return rect, ok


#: A segment's window may cover at most this many images' area, and hold at most this many poses.
MAX_WINDOW_AREA = 2.0
MAX_SEGMENT_POSES = 64


def plan(scene: MitsubaScene, cameras: list[np.ndarray], *, sub: int) -> list[Segment]:
    """Split poses into segments that one reference window covers (at most :data:`MAX_WINDOW_AREA`
    images, :data:`MAX_SEGMENT_POSES` poses), each referenced to its middle pose."""
    m = scene.manifest
    w, h = m.render.width, m.render.height
    f = focal_px(m.fov_deg, w)

    def split(lo: int, hi: int) -> list[Segment]:
        ref = np.asarray(cameras[(lo + hi - 1) // 2], float)
        box = window(scene, cameras[lo:hi], ref) if hi - lo <= MAX_SEGMENT_POSES else None
        if box is not None and ((box[2] - box[0]) * (box[3] - box[1]) <= MAX_WINDOW_AREA * w * h or hi - lo == 1):
            u0, v0, u1, v1 = box
            return [Segment(PinholeGrid(ref, f, w / 2, h / 2, float(u0), float(v0), int(u1 - u0) * sub,
                                        int(v1 - v0) * sub, sub), tuple(range(lo, hi)))]
        if hi - lo == 1:
            raise ValueError("parallax reuse: a pose sees a point behind its own reference camera")
        mid = (lo + hi) // 2
        return split(lo, mid) + split(mid, hi)

    return split(0, len(cameras))
