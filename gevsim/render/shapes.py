"""Small helpers for scene builders: placed shapes, materials and textures.

Textures come from photographs that ship inside scikit-image's wheel
(``skimage.data``) or are generated, so built-in scenes need no download.
Lengths are in metres; +y is up.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

#: A 3-vector (position, size, RGB) as a sequence of numbers.
Vec3 = Sequence[float]

TEXTURES = ("astronaut", "brick", "camera", "coffee", "chelsea", "moon", "grass", "gravel", "rocket", "text")


def _T():
    import mitsuba as mi

    return mi.ScalarTransform4f()


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decoding of values in [0, 1]."""
    x = np.asarray(x, np.float64)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


@functools.lru_cache(maxsize=32)
def photo(name: str, *, albedo: float = 0.8) -> np.ndarray:
    """A scikit-image photograph as linear reflectance (H, W, 3) float32 in [0, albedo]."""
    import skimage.data

    if name not in TEXTURES:
        raise ValueError(f"unknown texture {name!r}; choose one of {', '.join(TEXTURES)}")
    img = getattr(skimage.data, name)().astype(np.float64) / 255.0
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    return (albedo * srgb_to_linear(img[..., :3])).astype(np.float32)


def noise_texture(shape: tuple[int, int] = (256, 256), *, mean: float = 0.1, spread: float = 0.05,
                  seed: int = 0) -> np.ndarray:
    """Smooth grey value noise (asphalt, plaster): (H, W, 3) float32 reflectance."""
    rng = np.random.default_rng(seed)
    img = np.zeros(shape)
    for scale in (4, 16, 64):
        coarse = rng.standard_normal((shape[0] // scale + 2, shape[1] // scale + 2))
        img += np.kron(coarse, np.ones((scale, scale)))[: shape[0], : shape[1]] / 3
    img = np.clip(mean + spread * img, 0.01, 0.95)
    return np.repeat(img[..., None], 3, axis=2).astype(np.float32)


def diffuse(reflectance: Vec3 | np.ndarray) -> dict:
    """Lambertian BSDF from an RGB triple or an (H, W, 3) reflectance image.

    Images are flipped vertically because Mitsuba maps the first image row to
    v = 0, the bottom of a rectangle: photographs then hang upright.
    """
    import mitsuba as mi

    if isinstance(reflectance, np.ndarray) and reflectance.ndim == 3:
        image = np.ascontiguousarray(reflectance[::-1])
        tex = {"type": "bitmap", "bitmap": mi.Bitmap(image), "raw": True,
               "filter_type": "bilinear"}
        return {"type": "diffuse", "reflectance": tex}
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(reflectance)}}


def area_light() -> dict:
    """A placeholder area emitter; its radiance is set from the scene manifest."""
    return {"type": "area", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}


def _dress(shape: dict, bsdf, emitter) -> dict:
    """Attach a BSDF and/or an emitter to a shape dict."""
    if bsdf is not None:
        shape["bsdf"] = bsdf
    if emitter is not None:
        shape["emitter"] = emitter
    return shape


def rectangle(centre: Vec3, size: Sequence[float], *, facing: str, bsdf: dict | None = None,
              emitter: dict | None = None, spin_deg: float = 0.0) -> dict:
    """A ``size[0]`` x ``size[1]`` rectangle at ``centre`` whose front faces ``facing``.

    ``facing`` is one of '+x', '-x', '+y', '-y', '+z', '-z' (the normal).
    """
    rotations = {"+z": (None, 0), "-z": ((0, 1, 0), 180), "+y": ((1, 0, 0), -90), "-y": ((1, 0, 0), 90),
                 "+x": ((0, 1, 0), 90), "-x": ((0, 1, 0), -90)}
    if facing not in rotations:
        raise ValueError(f"facing must be one of {', '.join(rotations)}, got {facing!r}")
    axis, angle = rotations[facing]
    t = _T().translate(list(centre))
    if axis is not None:
        t = t.rotate(list(axis), angle)
    t = t.rotate([0, 0, 1], spin_deg).scale([size[0] / 2, size[1] / 2, 1])
    out = {"type": "rectangle", "to_world": t}
    return _dress(out, bsdf, emitter)


def box(centre: Vec3, size: Vec3, *, bsdf: dict | None = None, emitter: dict | None = None) -> dict:
    """An axis-aligned box (Mitsuba ``cube`` mesh) of full extents ``size``."""
    out = {"type": "cube", "to_world": _T().translate(list(centre)).scale([s / 2 for s in size])}
    return _dress(out, bsdf, emitter)


def sphere(centre: Vec3, radius: float, *, bsdf: dict | None = None, emitter: dict | None = None) -> dict:
    out = {"type": "sphere", "center": list(centre), "radius": float(radius)}
    return _dress(out, bsdf, emitter)


def cylinder(p0: Vec3, p1: Vec3, radius: float, *, bsdf: dict | None = None, emitter: dict | None = None) -> dict:
    out = {"type": "cylinder", "p0": list(p0), "p1": list(p1), "radius": float(radius)}
    return _dress(out, bsdf, emitter)


def room(width: float, depth: float, height: float, *, walls: dict, floor: dict, ceiling: dict,
         centre_z: float = 0.0) -> dict:
    """Six inward-facing rectangles of a room spanning x in [-w/2, w/2], y in [0, h], z about ``centre_z``."""
    w, d, h, z = width, depth, height, centre_z
    return {
        "floor": rectangle([0, 0, z], [w, d], facing="+y", bsdf=floor),
        "ceiling": rectangle([0, h, z], [w, d], facing="-y", bsdf=ceiling),
        "wall_back": rectangle([0, h / 2, z - d / 2], [w, h], facing="+z", bsdf=walls),
        "wall_front": rectangle([0, h / 2, z + d / 2], [w, h], facing="-z", bsdf=walls),
        "wall_left": rectangle([-w / 2, h / 2, z], [d, h], facing="+x", bsdf=walls),
        "wall_right": rectangle([w / 2, h / 2, z], [d, h], facing="-x", bsdf=walls),
    }
