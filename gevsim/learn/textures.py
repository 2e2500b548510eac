"""Gray textures for the planar training scenes (:mod:`gevsim.learn.planar`): photographs and procedural patterns.

Photographs are scikit-image's bundled ones (``skimage.data``, no download) of at least 256 px a side,
converted to gray with :func:`skimage.color.rgb2gray`'s weights (ITU-R BT.709: 0.2125 R + 0.7154 G + 0.0721 B),
written out elementwise so that the bits do not depend on the CPU's BLAS. :data:`HELD_OUT` (three of
scikit-image's and matplotlib's ``grace_hopper``) never serve for training; ``cat`` is excluded too: it is
``chelsea``.

Procedural textures are drawn from a seeded numpy Generator: ``dead_leaves`` (occluding disks and
rectangles of random gray with a power-law size distribution, the classic model of natural images' scale
invariance: Lee, Mumford & Huang, IJCV 2001), ``grating`` (an oriented sinusoid), ``checkerboard`` (rotated)
and ``noise`` (smooth value noise at a random scale). Every texture is gray in [0, 1], float64.
"""

from __future__ import annotations

import functools

import numpy as np

from gevsim import _portable as pm
from gevsim.errors import ConfigError, suggest

#: Never used for training: the held-out photographs of issue 38.
HELD_OUT = ("chelsea", "rocket", "coffee", "grace_hopper")
#: scikit-image photographs (bundled, >= 256 px a side) usable for training; "motorcycle" is the left view
#: of ``stereo_motorcycle``.
PHOTOS = ("astronaut", "brick", "camera", "cell", "clock", "coins", "grass", "gravel", "immunohistochemistry",
          "moon", "motorcycle", "retina")
#: Procedural kinds, each drawn from a Generator.
PROCEDURAL = ("dead_leaves", "grating", "checkerboard", "noise")
#: Default side of a procedural texture (px).
SIZE = 512

_BT709 = (0.2125, 0.7154, 0.0721)  # skimage.color.rgb2gray's weights


def gray(image: np.ndarray) -> np.ndarray:
    """An 8-bit (or [0, 1]) gray or RGB(A) image as gray float64 in [0, 1] (rgb2gray's weights)."""
    img = np.asarray(image)
    scale = 255.0 if img.dtype == np.uint8 else 1.0
    img = img.astype(np.float64) / scale
    if img.ndim == 3:
        img = _BT709[0] * img[..., 0] + _BT709[1] * img[..., 1] + _BT709[2] * img[..., 2]
    return np.clip(img, 0.0, 1.0)


@functools.lru_cache(maxsize=32)
def _photo(name: str) -> np.ndarray:
    if name == "grace_hopper":
        from matplotlib import cbook
        from PIL import Image

        with Image.open(cbook.get_sample_data("grace_hopper.jpg", asfileobj=False)) as im:
            raw = np.asarray(im.convert("RGB"))
    else:
        import skimage.data

        raw = skimage.data.stereo_motorcycle()[0] if name == "motorcycle" else getattr(skimage.data, name)()
    out = gray(raw)
    out.setflags(write=False)
    return out


def dead_leaves(rng: np.random.Generator, size: int = SIZE) -> np.ndarray:
    """Dead leaves: disks and rectangles of uniform random gray, radii ~ r^-3 in [2, size / 5] px, painted
    until they cover the image (each new one on top)."""
    img = np.full((size, size), rng.uniform())
    rmin, rmax = 2.0, size / 5.0
    yy, xx = np.mgrid[0:size, 0:size]
    for _ in range(int(30 * size * size / (rmin * rmax * np.pi))):  # ~ area coverage many times over
        u = rng.uniform()
        r = rmin / np.sqrt(1.0 - u * (1.0 - (rmin / rmax) * (rmin / rmax)))  # inverse CDF of r^-3 on [rmin, rmax]
        cx, cy, value, square = rng.uniform(0, size), rng.uniform(0, size), rng.uniform(), rng.uniform() < 0.3
        x0, x1 = max(int(cx - r), 0), min(int(cx + r) + 1, size)
        y0, y1 = max(int(cy - r), 0), min(int(cy + r) + 1, size)
        if x0 >= x1 or y0 >= y1:
            continue
        if square:
            img[y0:y1, x0:x1] = value
        else:
            dx, dy = xx[y0:y1, x0:x1] - cx, yy[y0:y1, x0:x1] - cy
            patch = img[y0:y1, x0:x1]
            patch[dx * dx + dy * dy <= r * r] = value
    return img


def _rotated_coords(rng: np.random.Generator, size: int) -> tuple[np.ndarray, float, np.ndarray]:
    """Coordinates along and across a random direction (px), and a period in [6, size / 4] px (log-uniform)."""
    angle = rng.uniform(0.0, np.pi)
    period = float(pm.exp(rng.uniform(*pm.log(np.array([6.0, size / 4.0])))))
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
    return xx * pm.cos(angle) + yy * pm.sin(angle), period, (yy * pm.cos(angle) - xx * pm.sin(angle))


def grating(rng: np.random.Generator, size: int = SIZE) -> np.ndarray:
    """An oriented sinusoidal grating of random period, angle, phase and contrast in [0.3, 1]."""
    along, period, _ = _rotated_coords(rng, size)
    phase, contrast = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(0.3, 1.0)
    return 0.5 + 0.5 * contrast * pm.sin(2.0 * np.pi * along / period + phase)


def checkerboard(rng: np.random.Generator, size: int = SIZE) -> np.ndarray:
    """A rotated checkerboard of random square size, two random grays."""
    along, period, across = _rotated_coords(rng, size)
    low, high = np.sort(rng.uniform(0.0, 1.0, 2))
    odd = (np.floor(along / period) + np.floor(across / period)) % 2 == 1
    return np.where(odd, high, low)


def noise(rng: np.random.Generator, size: int = SIZE) -> np.ndarray:
    """Smooth value noise: Gaussian noise on a grid of random spacing in [2, size / 4] px, bilinearly
    interpolated, plus a finer octave at half the amplitude; stretched to [0, 1]."""
    spacing = float(pm.exp(rng.uniform(*pm.log(np.array([2.0, size / 4.0])))))
    img = np.zeros((size, size))
    for octave, amplitude in ((spacing, 1.0), (max(spacing / 4.0, 1.0), 0.5)):
        n = int(np.ceil(size / octave)) + 2
        grid = rng.standard_normal((n, n))
        pos = np.arange(size) / octave
        i = np.floor(pos).astype(np.intp)
        f = pos - i
        rows = grid[i] * (1.0 - f)[:, None] + grid[i + 1] * f[:, None]
        img += amplitude * (rows[:, i] * (1.0 - f)[None, :] + rows[:, i + 1] * f[None, :])
    low, high = img.min(), img.max()
    return (img - low) / (high - low) if high > low else np.full_like(img, 0.5)


_KINDS = {"dead_leaves": dead_leaves, "grating": grating, "checkerboard": checkerboard, "noise": noise}


def texture(name: str, rng: np.random.Generator | None = None, *, size: int = SIZE) -> np.ndarray:
    """The texture ``name`` (H, W) gray in [0, 1], float64: a photograph (:data:`PHOTOS`, :data:`HELD_OUT`) as it
    is, or a procedural kind (:data:`PROCEDURAL`) of ``size`` x ``size`` px drawn from ``rng`` (needed)."""
    if name in PHOTOS or name in HELD_OUT:
        return _photo(name).copy()
    if name not in _KINDS:
        choices = (*PHOTOS, *HELD_OUT, *PROCEDURAL)
        raise ConfigError(f"unknown texture {name!r}{suggest(name, choices)}; choose from {', '.join(choices)}")
    if rng is None:
        raise ValueError(f"procedural texture {name!r} needs a numpy Generator (rng=)")
    return _KINDS[name](rng, int(size))
