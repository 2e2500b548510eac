"""Lens: scene radiance to focal-plane irradiance (the camera equation).

For a thin lens focused at infinity, the irradiance on the image plane at
field angle theta is

    E = L * T * pi / (4 N^2) * cos^4(theta)

with L the scene radiance, T the lens transmission and N the f-number
(Horn, *Robot Vision*, MIT Press 1986, sec. 10.3; Healey & Kondepudy,
"Radiometric CCD camera calibration and noise estimation", IEEE TPAMI 16(3),
1994). For close objects replace N by the working f-number N (1 + m), m the
magnification; vignetting beyond cos^4 is not modelled.

The formula is linear in L, so it applies unchanged to gevsim's
"photopic-equivalent radiance" (Y = L_v / 683) and to every light-group basis
image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from gevsim import _portable as pm
from gevsim._validate import real, real_array, size

__all__ = ["Lens", "focal_plane_irradiance", "field_angle_map", "cos4_map"]


@dataclass(frozen=True)
class Lens:
    """A thin camera lens.

    Parameters
    ----------
    f_number : float
        Relative aperture N = f / D (> 0). Default f/2, a typical fast
        machine-vision lens (assumed).
    transmission : float
        Optical transmission T in (0, 1]. Default 0.9, typical of a
        multi-coated glass lens (assumed; 0.85-0.95 is common).
    focal_length_m : float
        Focal length in metres (> 0). Default 8 mm, a typical C/CS-mount lens
        for the small sensors of event cameras (assumed). Used only to relate
        field of view and pixel pitch, not by the camera equation.
    """

    f_number: float = 2.0
    transmission: float = 0.9
    focal_length_m: float = 8e-3

    def __post_init__(self):
        object.__setattr__(self, "f_number", real(self.f_number, "f_number", low=0.0, low_open=True))
        object.__setattr__(
            self, "transmission", real(self.transmission, "transmission", low=0.0, low_open=True, high=1.0)
        )
        object.__setattr__(
            self, "focal_length_m", real(self.focal_length_m, "focal_length_m", low=0.0, low_open=True)
        )

    @property
    def irradiance_factor(self) -> float:
        """On-axis E / L = T * pi / (4 N^2), in sr (W/m^2 per W/(m^2 sr))."""
        return self.transmission * math.pi / (4.0 * self.f_number * self.f_number)

    def fov_x_deg(self, width: int, *, pitch_m: float) -> float:
        """Horizontal field of view (degrees) of ``width`` pixels of pitch ``pitch_m``."""
        pitch_m = real(pitch_m, "pitch_m", low=0.0, low_open=True)
        return math.degrees(2.0 * float(pm.atan(width * pitch_m / (2.0 * self.focal_length_m))))


def focal_plane_irradiance(radiance: ArrayLike, *, lens: Lens, cos4: ArrayLike | None = None) -> np.ndarray:
    """Focal-plane irradiance E = L T pi/(4 N^2) cos^4(theta), in W/m^2.

    Parameters
    ----------
    radiance : array_like
        Scene radiance in W/(m^2 sr), finite and >= 0; shaped (H, W),
        (H, W, C) or with leading dimensions, e.g. (K, H, W) or (K, H, W, C).
    lens : Lens
    cos4 : array_like, optional
        (H, W) map of cos^4(theta) in [0, 1] (see :func:`cos4_map`); None means
        no off-axis falloff. It is matched against ``radiance`` as (..., H, W, C)
        first (when ``radiance.shape[-3:-1] == (H, W)``), else as (..., H, W).

    Returns
    -------
    numpy.ndarray
        Same shape as ``radiance``; float32 input stays float32.
    """
    if not isinstance(lens, Lens):
        raise TypeError(f"lens must be a gevsim.optics.Lens, got {type(lens).__name__}")
    L = real_array(radiance, "radiance", nonnegative=True)
    out = L * L.dtype.type(lens.irradiance_factor)
    if cos4 is None:
        return out
    c4 = real_array(cos4, "cos4", nonnegative=True).astype(L.dtype, copy=False)
    if c4.ndim != 2:
        raise ValueError(f"cos4 must be an (H, W) map, got shape {c4.shape}")
    n_big = int(np.count_nonzero(c4 > 1.0))
    if n_big:
        raise ValueError(f"cos4 has {n_big} value(s) > 1; cos^4(theta) lies in [0, 1]")
    if L.ndim >= 3 and L.shape[-3:-1] == c4.shape:
        return out * c4[:, :, None]
    if L.ndim >= 2 and L.shape[-2:] == c4.shape:
        return out * c4
    raise ValueError(
        f"cos4 map shape {c4.shape} matches neither (..., H, W, C) nor (..., H, W) "
        f"of radiance shape {L.shape}"
    )


def field_angle_map(width: int, height: int, *, fov_x_deg: float) -> np.ndarray:
    """Field angle theta (radians) of each pixel centre of a pinhole camera.

    Pixels are square, centres at (i + 0.5, j + 0.5), the optical axis through
    the image centre; the focal length in pixels is
    f = (width / 2) / tan(fov_x / 2) (Mitsuba's ``fov_axis="x"``).

    Returns
    -------
    numpy.ndarray
        (height, width) float64 array.
    """
    x, y, f_px = _pixel_offsets(width, height, fov_x_deg)
    return pm.atan(np.sqrt(x[None, :] * x[None, :] + y[:, None] * y[:, None]) / f_px)


def _pixel_offsets(width: int, height: int, fov_x_deg: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Pixel-centre offsets from the optical axis (x, y) and the focal length, all in pixels."""
    width, height = size(width, height)
    fov = real(fov_x_deg, "fov_x_deg", low=0.0, low_open=True)
    if fov >= 180.0:
        raise ValueError(f"fov_x_deg must be < 180 for a pinhole camera, got {fov!r}")
    f_px = (width / 2.0) / float(pm.tan(math.radians(fov) / 2.0))
    return np.arange(width) + 0.5 - width / 2.0, np.arange(height) + 0.5 - height / 2.0, f_px


def cos4_map(width: int, height: int, *, fov_x_deg: float) -> np.ndarray:
    """cos^4 of :func:`field_angle_map` (natural vignetting), (height, width).

    Computed without trigonometry: cos^2(theta) = f^2 / (f^2 + r^2) for a pixel at r from the axis.
    """
    x, y, f_px = _pixel_offsets(width, height, fov_x_deg)
    f2 = f_px * f_px
    c2 = f2 / (f2 + (x[None, :] * x[None, :] + y[:, None] * y[:, None]))
    return c2 * c2
