"""Photometry: luminance, lux, lamp spectra and their colour (colour-science).

gevsim's rendering convention: a rendered value is "photopic-equivalent
radiance" in W/(m^2 sr), i.e. its luminance Y (Rec.709 weights for RGB, the
single channel for mono) times K_m = 683 lm/W is the luminance in cd/m^2.
The same holds for irradiance: 683 * Y(E) is the illuminance in lux.

Lamp spectra come from ``colour.SDS_ILLUMINANTS`` (CIE 15:2018 tables: "A",
"D65", "FL1".."FL12", "FL3.x", high-pressure discharge "HP1".."HP5", LEDs
"LED-B1".."LED-V2", ...) and ``colour.SDS_LIGHT_SOURCES`` (measured lamps:
"HPS", "LPS", "Incandescent", "Mercury", "Metal Halide", "Cool White FL",
"Phosphor LED YAG", ...). Sodium: "HP1" is the CIE standard high-pressure
sodium lamp and "HP2" the colour-enhanced high-pressure sodium lamp
(CIE 15:2018); "HPS", "Super HPS", "C100S54 (HPS)",
"C100S54C (HPS)", "SDW-T 100W/LV (Super HPS)" are measured high-pressure and
"LPS" a low-pressure sodium lamp. "HP3".."HP5" are metal-halide lamps.
"""

from __future__ import annotations

import colour
import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import trapezoid

from gevsim._portable import combine
from gevsim._validate import real, real_array
from gevsim.errors import ConfigError, suggest

#: A lamp spectrum: a name :func:`lamp_spectrum` knows, or a colour SpectralDistribution.
Spectrum = str | colour.SpectralDistribution

__all__ = [
    "K_M_LM_PER_W",
    "REC709_LUMA_WEIGHTS",
    "luminance",
    "illuminance_lux",
    "lamp_names",
    "lamp_spectrum",
    "luminous_efficacy_lm_per_w",
    "photopic_lef",
    "spectrum_to_rgb",
]

#: Maximum luminous efficacy of photopic vision, lm/W (SI definition of the candela).
K_M_LM_PER_W = 683.0
#: Linear Rec.709 / sRGB luminance weights (ITU-R BT.709-6).
REC709_LUMA_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])

_LEF = "CIE 1924 Photopic Standard Observer"
_CMFS = "CIE 1931 2 Degree Standard Observer"


def luminance(rgb_or_mono: ArrayLike, *, mono: bool | None = None) -> np.ndarray:
    """Luminance Y of photopic-equivalent values (Rec.709 weights).

    Parameters
    ----------
    rgb_or_mono : array_like
        Linear RGB with a last axis of size 3, e.g. (H, W, 3) or (3,); or a
        mono image: a 2-D (H, W) array, or a last axis of size 1.
    mono : bool, optional
        Force the interpretation: True means every value is already Y (any
        shape); False means the last axis holds RGB (e.g. an (N, 3) list of
        triples, which would otherwise be read as a mono image); None infers
        it as described above.

    Returns
    -------
    numpy.ndarray
        Y, float, without the channel axis.
    """
    a = np.asarray(rgb_or_mono)
    if a.dtype.kind not in "biuf":
        raise TypeError(f"rgb_or_mono must be a real numeric array, got dtype {a.dtype}")
    if a.dtype.kind != "f":
        a = a.astype(np.float64)
    if mono or (mono is None and a.ndim == 2):
        return a.copy()
    if a.ndim >= 1 and a.shape[-1] == 3:
        return combine(a, REC709_LUMA_WEIGHTS)
    if a.ndim >= 1 and a.shape[-1] == 1:
        return a[..., 0].copy()
    raise ValueError(
        f"cannot read shape {a.shape} as RGB (last axis 3) or mono (2-D or last axis 1); "
        "pass mono=True for stacks of mono images"
    )


def illuminance_lux(irradiance_y: ArrayLike) -> np.ndarray:
    """Illuminance in lux = 683 lm/W * photopic-equivalent irradiance Y (W/m^2)."""
    return K_M_LM_PER_W * np.asarray(irradiance_y, dtype=float)


def lamp_names() -> tuple[str, ...]:
    """All lamp names :func:`lamp_spectrum` accepts (illuminants, then light sources)."""
    return tuple(colour.SDS_ILLUMINANTS.keys()) + tuple(colour.SDS_LIGHT_SOURCES.keys())


def lamp_spectrum(name: Spectrum, *, source: str | None = None, key: str | None = None) -> colour.SpectralDistribution:
    """Relative spectral power distribution of a named lamp.

    Parameters
    ----------
    name : str or colour.SpectralDistribution
        A key of ``colour.SDS_ILLUMINANTS`` or ``colour.SDS_LIGHT_SOURCES``
        (see module docstring; "HP1" = high-pressure sodium). A
        SpectralDistribution is returned as a copy.
    source, key : str, optional
        Config file and key named in the error for an unknown lamp.

    Returns
    -------
    colour.SpectralDistribution
        A copy (safe to modify); wavelengths in nm, relative power.

    Raises
    ------
    ConfigError
        Unknown name, with the closest known name when there is one.
    """
    if isinstance(name, colour.SpectralDistribution):
        return name.copy()
    if not isinstance(name, str):
        raise TypeError(f"lamp must be a name or colour.SpectralDistribution, got {name!r}")
    for table in (colour.SDS_ILLUMINANTS, colour.SDS_LIGHT_SOURCES):
        if name in table.keys():
            return table[name].copy()
    raise ConfigError(
        f"unknown lamp spectrum {name!r}{suggest(name, lamp_names())}; e.g. 'A' (incandescent), "
        "'D65', 'FL2'/'FL11' (fluorescent), 'HP1'/'HPS'/'LPS' (sodium), 'LED-B3' (white LED); "
        "all names: gevsim.optics.lamp_names()",
        source=source,
        key=key,
    )


def _on_grid(table, wavelengths: np.ndarray) -> np.ndarray:
    """Values of a colour (multi-)spectral table at ``wavelengths``, 0 outside its range."""
    values = np.asarray(table.values, dtype=float)
    w = np.asarray(table.wavelengths, dtype=float)
    if values.ndim == 1:
        return np.interp(wavelengths, w, values, left=0.0, right=0.0)
    return np.stack(
        [np.interp(wavelengths, w, values[:, i], left=0.0, right=0.0) for i in range(values.shape[1])],
        axis=-1,
    )


def photopic_lef(wavelength_nm: ArrayLike) -> np.ndarray:
    """CIE 1924 photopic luminous efficiency V(lambda), 0 outside 360-830 nm."""
    lef = colour.colorimetry.SDS_LEFS_PHOTOPIC[_LEF]
    return _on_grid(lef, np.asarray(wavelength_nm, dtype=float))


def _spectrum_arrays(sd) -> tuple[np.ndarray, np.ndarray]:
    sd = lamp_spectrum(sd)
    w = np.asarray(sd.wavelengths, dtype=float)
    s = np.asarray(sd.values, dtype=float)
    if w.size < 2:
        raise ValueError(f"spectrum {sd.name!r} must have >= 2 samples, got {w.size}")
    real_array(s, f"spectrum {sd.name!r}", nonnegative=True)
    return w, s


def luminous_efficacy_lm_per_w(sd: Spectrum) -> float:
    """Luminous efficacy of radiation, 683 * int V S dl / int S dl, in lm/W.

    Integrals use the trapezoid rule on the spectrum's own wavelengths, as
    ``colour.luminous_efficacy`` does (and agree with it), over the spectrum's
    range; V is 0 outside 360-830 nm.
    """
    w, s = _spectrum_arrays(sd)
    radiant = trapezoid(s, w)
    if radiant <= 0:
        raise ValueError("spectrum has zero radiant power")
    return float(K_M_LM_PER_W * trapezoid(photopic_lef(w) * s, w) / radiant)


def spectrum_to_rgb(sd: Spectrum, *, luminance_cd_m2: float) -> np.ndarray:
    """Linear sRGB emitter radiance with a lamp's chromaticity and a luminance.

    XYZ is integrated with colour's CIE 1931 2-degree colour matching
    functions on the spectrum's wavelengths (trapezoid rule; equivalent to
    ``colour.sd_to_XYZ(..., method="Integration")`` with the CMFS resampled to
    the lamp's grid), then converted with ``colour.XYZ_to_RGB`` to linear sRGB
    **without chromatic adaptation** (so D65 maps to R = G = B). Saturated
    lamps (e.g. "LPS") fall outside the sRGB gamut: negative components are
    clipped to 0 and the triple rescaled so that its Rec.709 luminance is
    exactly ``luminance_cd_m2 / 683`` (the chromaticity shifts slightly; the
    luminance is kept).

    Parameters
    ----------
    sd : str or colour.SpectralDistribution
        Lamp name (:func:`lamp_spectrum`) or spectrum.
    luminance_cd_m2 : float
        Luminance of the emitter in cd/m^2 (>= 0).

    Returns
    -------
    numpy.ndarray
        (3,) photopic-equivalent radiance in W/(m^2 sr).
    """
    lv = real(luminance_cd_m2, "luminance_cd_m2", low=0.0)
    w, s = _spectrum_arrays(sd)
    cmfs = _on_grid(colour.MSDS_CMFS[_CMFS], w)
    xyz = trapezoid(cmfs * s[:, None], w, axis=0)
    if not xyz[1] > 0:
        raise ValueError("spectrum has no luminance (Y = 0): cannot give it a luminance")
    rgb = colour.XYZ_to_RGB(
        xyz / xyz[1], "sRGB", None, chromatic_adaptation_transform=None, apply_cctf_encoding=False
    )
    rgb = np.clip(np.asarray(rgb, dtype=float), 0.0, None)
    y = float(combine(rgb, REC709_LUMA_WEIGHTS))
    if not y > 0:
        raise ValueError("spectrum maps to black in sRGB after clipping negative components")
    return rgb * (lv / K_M_LM_PER_W / y)
