"""Pixel geometry and silicon quantum efficiency.

The default QE curve is that of a generic front-side illuminated (FSI)
monochrome CMOS pixel: low in the blue (absorption in the gate/oxide stack
and shallow junction), a broad maximum of ~0.58 at 550-600 nm, falling to 0 at
the silicon band gap (~1100 nm). The numbers are **assumed/typical**, shaped
after the QE plots in EMVA 1288 reports of FSI sensors; they are not one
sensor's measured data. Pass a measured table for a specific sensor.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import colour
import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import PchipInterpolator

from gevsim._validate import increasing, real
from gevsim.optics.qe_curves import QE_CURVES, SILICON_QE_BSI, SILICON_QE_FSI  # noqa: F401 (they lived here)

#: A QE spec: None (the default silicon curve), a constant in (0, 1], a (wavelengths_nm, qe) pair
#: or a colour SpectralDistribution.
QE = float | tuple[Sequence[float], Sequence[float]] | colour.SpectralDistribution | None

__all__ = ["QE_CURVES", "SILICON_QE_BSI", "SILICON_QE_FSI", "silicon_qe", "silicon_qe_sd", "quantum_efficiency",
           "Pixel"]


def _as_table(table, *, name: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Validate a (wavelengths_nm, qe) pair or SpectralDistribution; return tuples."""
    if isinstance(table, colour.SpectralDistribution):
        w, v = table.wavelengths, table.values
    else:
        try:
            if isinstance(table, (str, bytes)):
                raise TypeError
            w, v = table
            w = np.asarray(w, dtype=float)
            v = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(
                f"{name} must be None, a number, a (wavelengths_nm, qe) pair or a "
                f"colour.SpectralDistribution, got {table!r}"
            ) from None
    w = np.asarray(w, dtype=float)
    v = np.asarray(v, dtype=float)
    if w.ndim != 1 or w.shape != v.shape or w.size < 2:
        raise ValueError(
            f"{name} table needs two 1-D sequences of equal length >= 2, got {w.shape}, {v.shape}"
        )
    increasing(w, f"{name} wavelength_nm", unit="nm")
    bad = int(np.count_nonzero(~np.isfinite(v) | (v < 0) | (v > 1)))
    if bad:
        raise ValueError(f"{name} has {bad} value(s) outside [0, 1]")
    return tuple(w.tolist()), tuple(v.tolist())


def silicon_qe(wavelength_nm: ArrayLike, *, table: QE = None) -> np.ndarray:
    """Quantum efficiency (electrons per photon) at ``wavelength_nm``.

    Parameters
    ----------
    wavelength_nm : array_like
        Wavelengths in nm.
    table : (wavelengths_nm, qe) or colour.SpectralDistribution, optional
        A user QE table; default :data:`SILICON_QE_FSI`.

    Returns
    -------
    numpy.ndarray
        Shape-preserving monotone (PCHIP) interpolation of the table, 0
        outside its wavelength range.
    """
    w, v = _as_table(SILICON_QE_FSI if table is None else table, name="qe")
    x = np.asarray(wavelength_nm, dtype=float)
    inside = (x >= w[0]) & (x <= w[-1])
    out = np.zeros_like(x)
    out[inside] = PchipInterpolator(w, v)(x[inside])
    return np.clip(out, 0.0, 1.0)


def silicon_qe_sd(*, table: QE = None) -> colour.SpectralDistribution:
    """:func:`silicon_qe` sampled every 5 nm over its table range, as a SpectralDistribution."""
    w, _ = _as_table(SILICON_QE_FSI if table is None else table, name="qe")
    grid = np.arange(w[0], w[-1] + 1e-9, 5.0)
    return colour.SpectralDistribution(silicon_qe(grid, table=table), grid, name="silicon QE")


def quantum_efficiency(wavelength_nm: ArrayLike, *, qe: QE = None) -> np.ndarray:
    """QE at ``wavelength_nm`` for a QE spec: None (default silicon curve), a
    constant in (0, 1], a (wavelengths_nm, qe) pair or a SpectralDistribution."""
    x = np.asarray(wavelength_nm, dtype=float)
    if qe is None:
        return silicon_qe(x)
    if isinstance(qe, (int, float, np.integer, np.floating)) and not isinstance(qe, bool):
        return np.full_like(x, real(qe, "qe", low=0.0, low_open=True, high=1.0))
    return silicon_qe(x, table=qe)


@dataclass(frozen=True)
class Pixel:
    """Photodiode geometry and QE of one pixel.

    Parameters
    ----------
    pitch_m : float
        Pixel pitch in metres. Default 18.5 um (iniVation DAVIS346 datasheet).
    fill_factor : float
        Photosensitive fraction of the pixel area, in (0, 1]. Default 0.22
        (DAVIS346 datasheet; no microlenses assumed).
    qe : None, float, (wavelengths_nm, qe) or colour.SpectralDistribution
        Quantum efficiency; None means :data:`SILICON_QE_FSI`. Tables are
        stored as a pair of tuples (hashable, comparable).
    """

    pitch_m: float = 18.5e-6
    fill_factor: float = 0.22
    qe: QE = None

    def __post_init__(self):
        object.__setattr__(self, "pitch_m", real(self.pitch_m, "pitch_m", low=0.0, low_open=True))
        object.__setattr__(
            self, "fill_factor", real(self.fill_factor, "fill_factor", low=0.0, low_open=True, high=1.0)
        )
        qe = self.qe
        if qe is not None:
            if isinstance(qe, (int, float, np.integer, np.floating)) and not isinstance(qe, bool):
                qe = real(qe, "qe", low=0.0, low_open=True, high=1.0)
            else:
                qe = _as_table(qe, name="qe")
        object.__setattr__(self, "qe", qe)

    @property
    def area_m2(self) -> float:
        """Photosensitive area, pitch^2 * fill_factor, in m^2."""
        return self.pitch_m * self.pitch_m * self.fill_factor

    def qe_at(self, wavelength_nm: ArrayLike) -> np.ndarray:
        """This pixel's QE at ``wavelength_nm``."""
        return quantum_efficiency(wavelength_nm, qe=self.qe)
