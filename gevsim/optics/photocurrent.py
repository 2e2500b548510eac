"""Photocurrent: illuminance at the pixel to photodiode current.

For light of relative spectrum S(lambda), the photocurrent per lumen reaching
the photodiode is

    R = q * int QE(l) * l / (h c) * S(l) dl  /  (683 * int V(l) S(l) dl)   [A/lm]

(photons per joule are l/(h c); V is the CIE 1924 photopic function). A pixel
with photopic-equivalent focal-plane irradiance Y (W/m^2) receives
683 * Y lux over its photosensitive area pitch^2 * fill_factor, so

    I_ph = 683 * Y * pitch^2 * fill_factor * R.

Integrals run over the lamp table's wavelengths (380-780 nm for most colour
tables): infrared beyond them is not counted, as if an IR-cut filter were
fitted. Constants from ``scipy.constants`` (CODATA).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import overload

import numpy as np
from numpy.typing import ArrayLike
from scipy import constants
from scipy.integrate import trapezoid

from gevsim._validate import real, real_array
from gevsim.optics.lens import Lens
from gevsim.optics.photometry import K_M_LM_PER_W, Spectrum, _spectrum_arrays, illuminance_lux, photopic_lef
from gevsim.optics.sensor import QE, Pixel, quantum_efficiency

__all__ = ["responsivity_a_per_lm", "photocurrent_a", "group_photocurrent_factors"]


def responsivity_a_per_lm(sd: Spectrum, *, qe: QE = None) -> float:
    """Photocurrent per lumen of incident light with spectrum ``sd``, in A/lm.

    Parameters
    ----------
    sd : str or colour.SpectralDistribution
        Lamp name (see :func:`gevsim.optics.lamp_spectrum`) or spectrum.
    qe : None, float, (wavelengths_nm, qe) or colour.SpectralDistribution
        Quantum efficiency; None means the default silicon curve.

    Examples
    --------
    Monochromatic 555 nm light with QE = 1 gives q l/(h c)/683 = 6.55e-4 A/lm.
    """
    w, s = _spectrum_arrays(sd)
    lumens = K_M_LM_PER_W * trapezoid(photopic_lef(w) * s, w)
    if not lumens > 0:
        raise ValueError("spectrum has no luminous flux (int V S = 0): responsivity per lumen undefined")
    photons_per_j = w * 1e-9 / (constants.h * constants.c)
    amps = constants.e * trapezoid(quantum_efficiency(w, qe=qe) * photons_per_j * s, w)
    return float(amps / lumens)


def photocurrent_a(irradiance_y: ArrayLike, *, pixel: Pixel, responsivity_a_per_lm: float) -> np.ndarray:
    """Photocurrent (A) of pixels with photopic-equivalent irradiance ``irradiance_y``.

    ``I = 683 * Y * pitch^2 * fill_factor * R``. Linear in Y, so it may be
    applied per light-group basis image with that group's responsivity and
    the results summed.

    Parameters
    ----------
    irradiance_y : array_like
        Focal-plane irradiance Y in W/m^2 (photopic-equivalent), >= 0.
    pixel : Pixel
    responsivity_a_per_lm : float
        From :func:`responsivity_a_per_lm` for the light's spectrum.
    """
    if not isinstance(pixel, Pixel):
        raise TypeError(f"pixel must be a gevsim.optics.Pixel, got {type(pixel).__name__}")
    r = real(responsivity_a_per_lm, "responsivity_a_per_lm", low=0.0)
    y = real_array(irradiance_y, "irradiance_y", nonnegative=True)
    return illuminance_lux(y) * (pixel.area_m2 * r)


@overload
def group_photocurrent_factors(spectra: Mapping[str, Spectrum], *, pixel: Pixel, lens: Lens) -> dict[str, float]: ...


@overload
def group_photocurrent_factors(spectra: Sequence[Spectrum], *, pixel: Pixel, lens: Lens) -> np.ndarray: ...


def group_photocurrent_factors(spectra: Mapping[str, Spectrum] | Sequence[Spectrum], *, pixel: Pixel,
                               lens: Lens) -> dict[str, float] | np.ndarray:
    """Photocurrent per unit photopic-equivalent radiance, one factor per light group.

    factor_k = T pi / (4 N^2) * 683 * pitch^2 * fill_factor * R_k   [A per W/(m^2 sr)]

    with R_k the responsivity (A/lm) for group k's lamp spectrum and the
    pixel's QE. The photocurrent image is ``sum_k factor_k * cos4 * Y_k``,
    with ``Y_k`` the luminance of group k's rendered basis image (already
    weighted by its waveform) and ``cos4`` from :func:`gevsim.optics.cos4_map`
    (**not** included in the factors).

    Parameters
    ----------
    spectra : mapping of name -> lamp, or sequence of lamps
        Each lamp a name or colour.SpectralDistribution.
    pixel : Pixel
    lens : Lens

    Returns
    -------
    dict or numpy.ndarray
        A dict with the same keys for a mapping, else a float64 array.
    """
    if not isinstance(pixel, Pixel):
        raise TypeError(f"pixel must be a gevsim.optics.Pixel, got {type(pixel).__name__}")
    if not isinstance(lens, Lens):
        raise TypeError(f"lens must be a gevsim.optics.Lens, got {type(lens).__name__}")
    scale = lens.irradiance_factor * K_M_LM_PER_W * pixel.area_m2

    def factor(sd: Spectrum) -> float:
        return scale * responsivity_a_per_lm(sd, qe=pixel.qe)

    if isinstance(spectra, Mapping):
        return {name: factor(sd) for name, sd in spectra.items()}
    if isinstance(spectra, str):
        raise TypeError("spectra must be a mapping or a sequence of lamps, not a single string")
    return np.array([factor(sd) for sd in spectra], dtype=float)
