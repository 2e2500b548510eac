"""A textured plane seen by a camera moving in 6 DoF: cheap, exactly converged frames for training sets.

As ESIM's planar renderer (Rebecq, Gehrig & Scaramuzza, "ESIM: an Open Event Camera Simulator", CoRL 2018),
each frame is the texture warped by the homography that maps the image onto the plane: no ray tracing,
no Monte Carlo noise. This is gevsim's own code.

Conventions: a pinhole camera (x right, y down, z forward), focal length ``f = (W / 2) / tan(fov / 2)`` px,
principal point at the image centre. The camera starts at the world origin looking along +z; the plane
passes through ``(0, 0, depth_m)`` with unit ``normal`` pointing to the camera's side. A pose is the
camera's rotation (camera to world) and its centre. Texture coordinates on the plane are metres along an
orthonormal basis of the plane divided by ``texel_m``; the texture tiles by mirroring, so the view is
always covered, and is sampled bilinearly at ``supersample`` x ``supersample`` points a pixel (area
averaging). A texture finer than ~2 texels a pixel (fronto-parallel, at ``depth_m``) is first
box-averaged by a whole factor (a mip level), against aliasing.

Every product here is written with + and * (no BLAS, numpy's SIMD sin/cos replaced by
:mod:`gevsim._portable`'s): the same frames on every CPU.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gevsim import _portable as pm

#: ``pose_at(t_s) -> (rotations (F, 3, 3) camera to world, centres (F, 3) m)``.
PoseFn = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def rotation(rotvec: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors (..., 3) (axis x angle, rad; Rodrigues' formula)."""
    r = np.asarray(rotvec, np.float64)
    theta = np.sqrt(_dot(r, r))
    small = theta < 1e-12
    safe = np.where(small, 1.0, theta)
    k = r / safe[..., None]
    s, c = pm.sin(theta), pm.cos(theta)
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = np.zeros_like(kx)
    skew = np.stack([np.stack([zero, -kz, ky], -1), np.stack([kz, zero, -kx], -1),
                     np.stack([-ky, kx, zero], -1)], -2)
    skew2 = (skew[..., :, :, None] * skew[..., None, :, :]).sum(-2)  # skew x skew, 3 terms: no BLAS
    eye = np.broadcast_to(np.eye(3), skew.shape)
    out = eye + s[..., None, None] * skew + (1.0 - c)[..., None, None] * skew2
    return np.where(small[..., None, None], eye, out)


def plane_basis(normal: np.ndarray, angle_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """An orthonormal basis (e1, e2) of the plane with unit ``normal``, turned by ``angle_rad`` about it; for
    normal (0, 0, -1) and angle 0 it is the camera's x and y axes."""
    n = np.asarray(normal, np.float64)
    x = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = x - _dot(x, n) * n
    e1 = e1 / np.sqrt(_dot(e1, e1))
    e2 = _cross(e1, n)
    c, s = float(pm.cos(angle_rad)), float(pm.sin(angle_rad))
    return c * e1 + s * e2, c * e2 - s * e1


def homographies(rotations: np.ndarray, centres: np.ndarray, *, focal_px: float, depth_m: float,
                 normal: np.ndarray, basis: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(F, 3, 3): rows ``(r_a, r_b, r_w)`` such that a pixel ``m = (u, v, 1)`` (from the image centre) sees the
    plane point at ``(r_a . m / r_w . m, r_b . m / r_w . m)`` metres along ``basis`` from ``(0, 0, depth_m)``."""
    n = np.asarray(normal, np.float64)
    kinv = np.diag([1.0 / focal_px, 1.0 / focal_px, 1.0])
    m = (np.asarray(rotations, np.float64)[:, :, :, None] * kinv[None, None]).sum(2)  # M = R K^-1: ray = M m
    q = np.asarray(centres, np.float64) - np.array([0.0, 0.0, depth_m])  # camera centre from the plane point

    def row(v: np.ndarray) -> np.ndarray:  # M^T v, (F, 3)
        return (m * v[None, :, None]).sum(1)

    mn = row(n)
    h = -_dot(q, n)  # n . (p0 - c)
    rows = [_dot(q, e)[:, None] * mn + h[:, None] * row(e) for e in basis]
    return np.stack([*rows, mn], axis=1)


def mip(tex: np.ndarray, factor: int) -> np.ndarray:
    """``tex`` box-averaged over ``factor`` x ``factor`` blocks (cropped to whole blocks)."""
    if factor <= 1:
        return tex
    h, w = (tex.shape[0] // factor) * factor, (tex.shape[1] // factor) * factor
    return tex[:h, :w].reshape(h // factor, factor, w // factor, factor).mean(axis=(1, 3))


def mirrored(tex: np.ndarray) -> np.ndarray:
    """``tex`` and its mirror images (2H, 2W): one period of the texture tiled by mirroring."""
    tiled = np.concatenate([tex, tex[::-1]], axis=0)
    return np.concatenate([tiled, tiled[:, ::-1]], axis=1)


def _sample(tiled: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear samples of the periodic texture ``tiled`` at texel coordinates (texel centres at integers)."""
    ph, pw = tiled.shape
    flat = np.pad(tiled, ((0, 1), (0, 1)), mode="wrap").ravel()  # one more row and column: i0 + 1 needs no wrap
    stride = pw + 1
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    idx = (y0.astype(np.intp) % ph) * stride + x0.astype(np.intp) % pw
    top = flat.take(idx) * (1.0 - fx) + flat.take(idx + 1) * fx
    bottom = flat.take(idx + stride) * (1.0 - fx) + flat.take(idx + stride + 1) * fx
    return top * (1.0 - fy) + bottom * fy


def focal_px(width: int, fov_deg: float) -> float:
    """Focal length in pixels of a ``width`` px image with horizontal field of view ``fov_deg``."""
    return 0.5 * width / float(pm.tan(np.deg2rad(fov_deg) / 2.0))


def render_planar(tex: np.ndarray, *, width: int, height: int, fov_deg: float, t_s: np.ndarray, depth_m: float,
                  normal: np.ndarray, pose_at: PoseFn, texel_m: float, origin_px: tuple[float, float] = (0.0, 0.0),
                  angle_rad: float = 0.0, supersample: int = 3, block: int = 16) -> np.ndarray:
    """Frames (F, H, W) float64 of the gray texture ``tex`` on a plane, at the poses ``pose_at(t_s)``.

    ``texel_m``: a texel's side on the plane; ``origin_px``: the texture coordinate at ``(0, 0, depth_m)``;
    ``angle_rad``: the texture's turn in the plane. The values are the texture's, area-averaged.
    """
    tex = np.asarray(tex, np.float64)
    n = np.asarray(normal, np.float64)
    if tex.ndim != 2 or min(tex.shape) < 2:
        raise ValueError(f"render_planar: tex must be a 2-D gray image, got shape {tex.shape}")
    n = n / np.sqrt(_dot(n, n))
    if not n[2] < 0.0:
        raise ValueError(f"render_planar: the plane's normal must face the camera (z < 0), got {tuple(normal)}")
    f = focal_px(width, fov_deg)
    factor = max(1, int(depth_m / f / texel_m))  # texels a pixel, fronto-parallel at depth_m
    tiled = mirrored(mip(tex, factor))
    texel = texel_m * factor
    ox, oy = origin_px[0] / factor, origin_px[1] / factor
    s = int(supersample)
    sub = (np.arange(s) + 0.5) / s - 0.5
    u = (np.arange(width)[:, None] + 0.5 + sub[None, :] - 0.5 * width).ravel()  # column-major subsamples
    v = (np.arange(height)[:, None] + 0.5 + sub[None, :] - 0.5 * height).ravel()
    uu, vv = np.tile(u, v.size), np.repeat(v, u.size)  # row-major over (row subsamples, column subsamples)
    rot, centres = pose_at(np.asarray(t_s, np.float64))
    hom = homographies(rot, centres, focal_px=f, depth_m=depth_m, normal=n, basis=plane_basis(n, angle_rad))
    out = np.empty((len(hom), height, width))
    for k in range(0, len(hom), block):
        hb = hom[k:k + block]
        a, b, w = (hb[:, r, 0, None] * uu + hb[:, r, 1, None] * vv + hb[:, r, 2, None] for r in range(3))
        w = np.minimum(w, -1e-6)  # rays hit the plane where n . d < 0; clamp grazing ones
        vals = _sample(tiled, a / w / texel + ox, b / w / texel + oy)
        vals = vals.reshape(len(hb), height, s, width, s)
        out[k:k + block] = vals.mean(axis=(2, 4))
    return out


@dataclass(frozen=True)
class Trajectory:
    """A smooth 6-DoF camera path: centre ``velocity_m_s * t + sway_m * (sin(w t + phase) - sin(phase))``
    (per axis), rotation vector ``rock_rad * (sin(w t + phase) - sin(phase)) + (0, 0, roll_rad_s * t)``,
    ``w = 2 pi frequency_hz``; camera axes at t = 0 are the world's."""

    velocity_m_s: tuple[float, float, float]
    sway_m: tuple[float, float, float]
    rock_rad: tuple[float, float, float]
    roll_rad_s: float
    frequency_hz: float
    phase_rad: tuple[float, float, float, float, float, float]

    def __call__(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t_s, np.float64)[:, None]
        ph = np.asarray(self.phase_rad, np.float64)[None, :]
        wave = pm.sin(2.0 * np.pi * self.frequency_hz * t + ph) - pm.sin(ph)  # (F, 6)
        centre = np.asarray(self.velocity_m_s)[None] * t + np.asarray(self.sway_m)[None] * wave[:, :3]
        rotvec = np.asarray(self.rock_rad)[None] * wave[:, 3:] + np.array([0.0, 0.0, self.roll_rad_s])[None] * t
        return rotation(rotvec), centre
