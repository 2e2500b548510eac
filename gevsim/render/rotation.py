"""Pure camera rotation: every pose is a resampling of one wider converged render.

A camera that turns about a fixed centre sees the same radiance along each
direction at every pose: there is no parallax. A pixel of pose p is a small
region of the image plane of a reference camera (:func:`~gevsim.render.rays.map_view`),
and its value (Mitsuba's box pixel filter: the mean radiance over the pixel)
is the mean of the reference image over that region. So the poses of a
segment are rendered once, as a window of the reference image plane that
covers them all, cut into ``sub`` x ``sub`` cells per pixel (a
:class:`~gevsim.render.rays.PinholeGrid`) and rendered to the noise target
(the stop rule measured on whole pixels), and each pose is the exact box
integral of that piecewise-constant cell image over its pixels' footprints
(:func:`box_resample`).

What is approximated, and by how much: (1) inside a cell the radiance is taken
as constant, so a footprint edge that cuts a cell mixes it in by area (a blur
of at most a cell, 1/sub px: :data:`SUB` is measured in benchmarks/README.md);
(2) a footprint is taken as the axis-aligned rectangle through its mapped edge
midpoints (exact for a pan about the image's vertical axis; under a rotation
about the view axis it is not: such segments are refused, see :func:`plan`).

Render noise: each pose's image and its noise sample are the same linear map
of the reference render and its noise sample, so the noise sample still has the
variance of the image's error, and both are correlated across poses exactly as
the images are. The render-noise floor built from them
(:func:`gevsim.emulation.driver.render_noise_floor`) is computed as for any
basis; the reused noise is a static pattern that moves with the image instead
of being redrawn at every pose, as independent per-pose renders did.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from gevsim.render.rays import PinholeGrid, focal_px, map_view

log = logging.getLogger("gevsim.render.basis")

#: Bump when the reference render's layout or its resampling changes (its cache key holds it).
CACHE_VERSION = 1
#: Cells per pixel along each axis of the reference render (measured: benchmarks/README.md, rotation reuse).
SUB = 3
#: Cells of margin around the poses' footprints.
MARGIN_PX = 2
#: A segment's reference window may cover at most this many images' area; wider pans are split.
MAX_WINDOW_AREA = 4.0
#: Largest rectangle error allowed: the footprint's corners may lie this far (px) off its rectangle.
MAX_SHEAR_PX = 0.05


@dataclass(frozen=True)
class Segment:
    """Poses ``poses`` (indices) are resamplings of the render of ``grid``."""

    grid: PinholeGrid
    poses: tuple[int, ...]


def same_centre(cameras: list[np.ndarray], *, tol_m: float = 1e-9) -> bool:
    """Whether every camera-to-world matrix has the same centre (a pure rotation)."""
    origins = np.array([np.asarray(c, float)[:3, 3] for c in cameras])
    return bool(np.all(np.abs(origins - origins[0]) <= tol_m))


def _window(cameras: list[np.ndarray], ref: np.ndarray, *, fov_deg: float, width: int,
            height: int) -> tuple[float, float, float, float] | None:
    """(u_min, v_min, u_max, v_max) on ``ref``'s image plane covering every camera's image, or None."""
    f = focal_px(fov_deg, width)
    probe = PinholeGrid(ref, f, width / 2, height / 2, 0.0, 0.0, 1, 1, 1)
    boxes = []
    for cam in cameras:
        corners = map_view(probe, cam, width=width, height=height)[[0, 0, -1, -1], [0, -1, 0, -1]]
        if not np.isfinite(corners).all():
            return None
        boxes.append(np.r_[corners.min(axis=0), corners.max(axis=0)])
    b = np.array(boxes)
    return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())


def plan(cameras: list[np.ndarray], *, fov_deg: float, width: int, height: int,
         sub: int | None = None) -> list[Segment]:
    """Split poses into segments whose footprints one reference window covers (at most
    ``MAX_WINDOW_AREA`` images), each referenced to its middle pose.

    Raises ValueError for a single pose whose footprints are not near-rectangles there
    (a roll of the camera about its view axis), which this method does not resample.
    ``sub``: cells per pixel (default :data:`SUB`).
    """
    sub = SUB if sub is None else sub

    def split(lo: int, hi: int) -> list[Segment]:
        ref = np.asarray(cameras[(lo + hi - 1) // 2], float)
        box = _window(cameras[lo:hi], ref, fov_deg=fov_deg, width=width, height=height)
        if box is not None:
            u0, v0 = math.floor(box[0]) - MARGIN_PX, math.floor(box[1]) - MARGIN_PX
            u1, v1 = math.ceil(box[2]) + MARGIN_PX, math.ceil(box[3]) + MARGIN_PX
            if (u1 - u0) * (v1 - v0) <= MAX_WINDOW_AREA * width * height or hi - lo == 1:
                grid = PinholeGrid(ref, focal_px(fov_deg, width), width / 2, height / 2, float(u0), float(v0),
                                   (u1 - u0) * sub, (v1 - v0) * sub, sub)
                return [Segment(grid, tuple(range(lo, hi)))]
        if hi - lo == 1:
            raise ValueError("rotation reuse: a pose looks more than 90 degrees away from its reference")
        mid = (lo + hi) // 2
        return split(lo, mid) + split(mid, hi)

    return split(0, len(cameras))


def footprints(grid: PinholeGrid, camera: np.ndarray, *, width: int, height: int) -> np.ndarray:
    """(4, H, W): x0, y0, x1, y1 of each pixel's footprint on ``grid`` (cell units), the rectangle
    through the midpoints of its mapped edges. Raises ValueError where a mapped footprint is not
    close to that rectangle (``MAX_SHEAR_PX``) or leaves the grid."""
    c = map_view(grid, camera, width=width, height=height)
    rect = edge_rect(c)
    x0, y0, x1, y1 = rect
    shear = max(np.abs(c[:-1, :-1, 0] - c[1:, :-1, 0]).max(), np.abs(c[:-1, :-1, 1] - c[:-1, 1:, 1]).max())
    if not np.isfinite(rect).all() or shear > 2 * MAX_SHEAR_PX * grid.sub:
        raise ValueError(f"rotation reuse: pixel footprints are not rectangles on the reference (corners off by "
                         f"{shear / grid.sub / 2:.3g} px; the camera rolls about its view axis)")
    if x0.min() < 0 or y0.min() < 0 or x1.max() > grid.width or y1.max() > grid.height or (x1 <= x0).any() \
            or (y1 <= y0).any():
        raise ValueError("rotation reuse: a pixel footprint leaves the reference window")
    return rect


def edge_rect(c: np.ndarray) -> np.ndarray:
    """(4, H, W): x0, y0, x1, y1 of the axis-aligned rectangle through the midpoints of the edges of each
    quadrilateral of the (H + 1, W + 1, 2) corner map ``c``."""
    return np.stack([0.5 * (c[:-1, :-1, 0] + c[1:, :-1, 0]), 0.5 * (c[:-1, :-1, 1] + c[:-1, 1:, 1]),
                     0.5 * (c[:-1, 1:, 0] + c[1:, 1:, 0]), 0.5 * (c[1:, :-1, 1] + c[1:, 1:, 1])])


def box_resample(cells: np.ndarray, rect: np.ndarray, *, power: int = 1) -> np.ndarray:
    """(K, H, W, C) float32: the mean of the piecewise-constant image ``cells`` (K, Hc, Wc, C) over each
    rectangle ``rect`` (4, H, W; x0, y0, x1, y1 in cell units, :func:`footprints`): a sum over the cells
    each rectangle overlaps, weighted by the overlap's share of the rectangle's area (exact, and never
    negative for a non-negative image). ``power = 2`` sums with the squared weights instead: the
    variance of that mean when ``cells`` holds independent cells' variances. A rectangle's part outside
    the grid takes the nearest edge cell."""
    from gevsim.render._boxfilter import box_sums

    k, hc, wc, c = cells.shape
    flat = np.ascontiguousarray(np.moveaxis(cells, 0, 2).reshape(hc, wc, k * c))  # one pass serves K x C values
    x0, y0, x1, y1 = (np.ascontiguousarray(a, dtype=np.float64).ravel() for a in rect)
    total = box_sums(flat, x0, y0, x1, y1, power)
    return np.moveaxis(total.reshape(*rect.shape[1:], k, c), 2, 0).astype(np.float32)


def pixel_error(se_map: np.ndarray, grid: PinholeGrid, rect: np.ndarray) -> np.ndarray:
    """(H, W) float32 ln standard error of a pose's pixels from the reference's pixel error map
    ``se_map``: a cell holds 1/sub^2 of its pixel's samples (variance sub^2 times the pixel's), cells
    are independent, and a pose pixel is a weighted mean of cells (variance: the sum of squared
    weights times theirs; equal to its reference pixel's where the footprints coincide)."""
    var = np.square(se_map.astype(np.float64)) * grid.sub**2
    cells = np.repeat(np.repeat(var, grid.sub, axis=0), grid.sub, axis=1)[None, ..., None]
    return np.sqrt(box_resample(cells, rect, power=2)[0, ..., 0])
