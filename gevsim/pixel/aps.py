"""Linear APS frames (DAVIS-like active pixel sensor) with the EMVA 1288 noise model.

A global-shutter frame integrates the photocurrent over its exposure window, so
lamp flicker shows up as exposure-phase-dependent brightness. The noise model
is that of EMVA Standard 1288 (release 4.0, linear sensors): photo and dark
electrons are Poisson, the temporal dark noise ``sigma_d`` is Gaussian, the
output is ``y = K (e + n_d) + offset`` quantised to ``bit_depth`` bits; DSNU
and PRNU are fixed patterns drawn once per sensor.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from gevsim._validate import increasing, integer, real, real_array
from gevsim.config import FieldError, FromTable

__all__ = ["ApsParams", "ApsSensor", "exposure_electrons", "photon_transfer", "system_gain_from_ptc"]


@dataclass(frozen=True)
class ApsParams(FromTable):
    """EMVA 1288 parameters of a linear APS pixel and its ADC.

    Defaults are DAVIS346-like. ``bit_depth=10`` and a dynamic range of
    ~56 dB (``full_well_e / read_noise_e``) are from the iniVation DAVIS346
    datasheet, from memory, unchecked; every other default is **assumed**.

    ``fill_factor_ratio`` is the APS photocurrent as a fraction of the DVS
    photocurrent (> 0); DAVIS pixels share one photodiode, so 1.
    """

    TABLE = "aps"

    full_well_e: float = 20000.0         #: saturation capacity, e- (> 0)
    read_noise_e: float = 30.0           #: temporal dark noise sigma_d, e- rms
    dark_current_e_per_s: float = 500.0  #: mean dark current, e-/s
    dsnu_e: float = 20.0                 #: DSNU: spatial sigma of a per-pixel dark offset, e-
    prnu: float = 0.01                   #: PRNU: spatial relative sigma of the gain, in [0, 1)
    system_gain_dn_per_e: float = 0.048  #: overall system gain K, DN/e- (> 0)
    offset_dn: float = 32.0              #: black level, DN, in [0, 2**bit_depth - 1]
    bit_depth: int = 10                  #: ADC resolution, 8..16 bits
    fill_factor_ratio: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "bit_depth", integer(self.bit_depth, "bit_depth", low=8, high=16))
        for name, low, low_open in (("full_well_e", 0.0, True), ("read_noise_e", 0.0, False),
                                    ("dark_current_e_per_s", 0.0, False), ("dsnu_e", 0.0, False),
                                    ("prnu", 0.0, False), ("system_gain_dn_per_e", 0.0, True),
                                    ("offset_dn", 0.0, False), ("fill_factor_ratio", 0.0, True)):
            object.__setattr__(self, name, real(getattr(self, name), name, low=low, low_open=low_open))
        if self.prnu >= 1.0:
            raise FieldError("prnu", f"prnu={self.prnu!r} must be < 1 (a relative sigma)")
        if self.offset_dn > self.max_dn:
            raise FieldError("offset_dn",
                              f"offset_dn={self.offset_dn!r} exceeds 2**bit_depth - 1 = {self.max_dn}")

    @property
    def max_dn(self) -> int:
        """Largest output code, ``2**bit_depth - 1``."""
        return (1 << self.bit_depth) - 1


def exposure_electrons(photocurrent_a: ArrayLike, t_edges_s: ArrayLike, frame_start_s: ArrayLike,
                       exposure_s: float) -> np.ndarray:
    """Mean photo-electrons collected in each global-shutter exposure window.

    Parameters
    ----------
    photocurrent_a : array_like, shape (T, H, W)
        Photocurrent in A, ``photocurrent_a[k]`` held over ``[t_edges_s[k], t_edges_s[k+1])``.
    t_edges_s : array_like, shape (T + 1,)
        Strictly increasing step edges in s.
    frame_start_s : array_like, shape (F,)
        Start of each exposure window in s (a scalar means F = 1).
    exposure_s : float
        Exposure time in s (> 0).

    Returns
    -------
    numpy.ndarray, shape (F, H, W), float64
        ``int I(t) dt / q`` over ``[start, start + exposure_s)``, exact for the
        step current (cumulative charge at the edges plus the fractional step).
    """
    current = real_array(photocurrent_a, "photocurrent_a", nonnegative=True, dtype=np.float64)
    edges = increasing(np.asarray(t_edges_s, dtype=np.float64), "t_edges_s")
    if current.ndim < 1:
        raise ValueError(f"photocurrent_a must have shape (T, H, W), got {current.shape}")
    if edges.shape != (current.shape[0] + 1,):
        raise ValueError(f"t_edges_s must have shape (T + 1,) = ({current.shape[0] + 1},) for "
                         f"photocurrent_a of shape {current.shape}, got {edges.shape}")
    starts = real_array(np.atleast_1d(np.asarray(frame_start_s, dtype=np.float64)), "frame_start_s")
    if starts.ndim != 1:
        raise ValueError(f"frame_start_s must be a 1-D array, got shape {starts.shape}")
    exposure = real(exposure_s, "exposure_s", low=0.0, low_open=True)
    ends = starts + exposure
    tol = 4 * np.finfo(np.float64).eps * max(abs(edges[0]), abs(edges[-1]), exposure)
    outside = (starts < edges[0] - tol) | (ends > edges[-1] + tol)
    if np.any(outside):
        f = int(np.argmax(outside))
        raise ValueError(f"exposure window {f} [{starts[f]!r}, {ends[f]!r}) s lies outside the "
                         f"photocurrent's time range [{edges[0]!r}, {edges[-1]!r}] s")
    charge = np.zeros((edges.size,) + current.shape[1:])
    np.cumsum(current * np.diff(edges).reshape((-1,) + (1,) * (current.ndim - 1)), axis=0, out=charge[1:])

    def charge_at(t: np.ndarray) -> np.ndarray:
        t = np.clip(t, edges[0], edges[-1])
        k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, current.shape[0] - 1)
        dt = (t - edges[k]).reshape((-1,) + (1,) * (current.ndim - 1))
        return charge[k] + current[k] * dt

    from scipy.constants import e as ELEMENTARY_CHARGE_C  # here: reading a preset needs no scipy

    return (charge_at(ends) - charge_at(starts)) / ELEMENTARY_CHARGE_C


class ApsSensor:
    """An (H, W) APS array with fixed DSNU and PRNU patterns drawn once from ``rng``.

    DSNU offsets are ``N(0, dsnu_e)`` electrons, PRNU gains ``1 + prnu N(0, 1)``
    clipped at 0; both are drawn in ``__init__`` and kept for every frame.
    """

    def __init__(self, shape: Sequence[int], params: ApsParams, *, rng: np.random.Generator):
        if not isinstance(params, ApsParams):
            raise TypeError(f"params must be an ApsParams, got {type(params).__name__}")
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        shape = tuple(int(n) for n in shape)
        if len(shape) != 2 or min(shape) < 1:
            raise ValueError(f"shape must be (H, W) with H, W >= 1, got {shape}")
        self.shape, self.params = shape, params
        self.dsnu_offset_e = rng.normal(0.0, params.dsnu_e, shape)
        self.prnu_gain = np.maximum(1.0 + params.prnu * rng.standard_normal(shape), 0.0)

    def _check(self, electrons_mean, exposure_s) -> tuple[np.ndarray, float]:
        electrons = real_array(electrons_mean, "electrons_mean", nonnegative=True, dtype=np.float64)
        if electrons.shape[-2:] != self.shape:
            raise ValueError(f"electrons_mean must end in the sensor shape {self.shape}, "
                             f"got {electrons.shape}")
        return electrons, real(exposure_s, "exposure_s", low=0.0)

    def read(self, electrons_mean: ArrayLike, exposure_s: float, *, rng: np.random.Generator,
             output: str = "dn") -> np.ndarray:
        """Read noisy frames (EMVA 1288) from the mean photo-electrons of each exposure.

        Parameters
        ----------
        electrons_mean : array_like, shape (F, H, W) or (H, W)
            Mean photo-electrons per exposure from the DVS photocurrent, e.g.
            :func:`exposure_electrons`; scaled by ``fill_factor_ratio``.
        exposure_s : float
            Exposure time in s (sets the dark signal).
        rng : numpy.random.Generator
            Temporal noise source; the same seed gives identical frames.
        output : {"dn", "float"}
            ``"dn"``: uint16 codes; ``"float"``: float32 ``DN / (2**bit_depth - 1)``.

        Returns
        -------
        numpy.ndarray
            Same shape as ``electrons_mean``.
        """
        if output not in ("dn", "float"):
            raise ValueError(f"output must be 'dn' or 'float', got {output!r}")
        electrons, exposure = self._check(electrons_mean, exposure_s)
        p = self.params
        lam = (self.prnu_gain * p.fill_factor_ratio * electrons
               + p.dark_current_e_per_s * exposure + self.dsnu_offset_e)
        # Means far above full well saturate anyway; the cap keeps rng.poisson in range.
        lam = np.clip(lam, 0.0, 4.0 * p.full_well_e + 1e3)
        signal_e = np.minimum(rng.poisson(lam), p.full_well_e).astype(np.float64)
        signal_e += rng.normal(0.0, p.read_noise_e, signal_e.shape) if p.read_noise_e > 0 else 0.0
        dn = np.clip(np.rint(p.system_gain_dn_per_e * signal_e + p.offset_dn), 0, p.max_dn)
        return dn.astype(np.uint16) if output == "dn" else (dn / p.max_dn).astype(np.float32)

    def mean_dn(self, electrons_mean: ArrayLike, exposure_s: float) -> np.ndarray:
        """Noise-free expected DN without fixed patterns (float64), for tests.

        ``K min(fill_factor_ratio e + dark_current t, full_well) + offset``,
        clipped to the code range (Poisson spread at the full-well clip ignored).
        """
        electrons, exposure = self._check(electrons_mean, exposure_s)
        p = self.params
        e_total = p.fill_factor_ratio * electrons + p.dark_current_e_per_s * exposure
        e_total = np.minimum(e_total, p.full_well_e)
        return np.clip(p.system_gain_dn_per_e * e_total + p.offset_dn, 0.0, p.max_dn)


def photon_transfer(frames_a: ArrayLike, frames_b: ArrayLike, *, dark_a: ArrayLike | None = None,
                    dark_b: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mean and temporal variance of a pair of frames taken at the same exposure (EMVA 1288).

    ``mu_y = mean((a + b) / 2)`` and ``sigma_y^2 = var(a - b) / 2`` over the
    last two (H, W) axes; the pair difference cancels DSNU and PRNU. With a
    dark pair, its mean and variance (read noise, dark shot noise and the
    1/12 DN^2 quantisation noise) are subtracted.

    Returns
    -------
    (mu_y, sigma2_y) : float64 arrays of the leading shape (0-d for (H, W) frames), in DN and DN^2.
    """
    def stats(a, b, name):
        a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)  # no uint16 wrap-around
        if a.shape != b.shape or a.ndim < 2:
            raise ValueError(f"{name} frames must have equal shapes (..., H, W), got {a.shape} and {b.shape}")
        return 0.5 * (a + b).mean(axis=(-2, -1)), 0.5 * (a - b).var(axis=(-2, -1))

    mu, var = stats(frames_a, frames_b, "light")
    if (dark_a is None) != (dark_b is None):
        raise ValueError("give both dark_a and dark_b, or neither")
    if dark_a is not None:
        mu_d, var_d = stats(dark_a, dark_b, "dark")
        mu, var = mu - mu_d, var - var_d
    return mu, var


def system_gain_from_ptc(means: ArrayLike, variances: ArrayLike) -> float:
    """System gain ``K`` (DN/e-) as the least-squares slope of variance vs mean (photon transfer).

    EMVA 1288: ``sigma_y^2 - sigma_y.dark^2 = K (mu_y - mu_y.dark)``, so the
    slope is ``K`` when the points are shot-noise limited and below
    saturation (drop points near full well, where the variance collapses).
    """
    x, y = np.asarray(means, dtype=np.float64).ravel(), np.asarray(variances, dtype=np.float64).ravel()
    if x.shape != y.shape or x.size < 2 or not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError(f"need >= 2 finite (mean, variance) pairs of equal length, "
                         f"got {x.size} and {y.size}")
    if np.ptp(x) == 0:
        raise ValueError("means are all equal; the photon transfer slope is undefined")
    return float(np.polyfit(x, y, 1)[0])
