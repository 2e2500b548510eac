"""Optional denoising of light-group images with Intel Open Image Denoise (OIDN).

OIDN's ``RT`` filter (a U-Net trained on path-traced images) takes a noisy
HDR colour image and, as auxiliary guides, the first-hit albedo and shading
normal; with noise-free guides (``cleanAux``) it keeps texture and geometric
edges that the guides show and smooths the Monte Carlo noise in between
(Áfra, *Intel Open Image Denoise*, 2019-2024, https://www.openimagedenoise.org;
EventTracer, 2025, denoises low-spp renders for event simulation the same way).

It is a *biased* estimator: what it does to flicker-induced event rates was
measured against a high-spp reference (``benchmarks/flicker_convergence.py``,
figures in ``benchmarks/README.md``), and ``[render] denoise`` is off unless a
scene asks for it.

The library comes from the ``oidn`` wheel on PyPI (0.2.1, OIDN 1.4.3), which
bundles ``libOpenImageDenoise`` and ``libtbb`` but whose own import fails to
find ``libtbb.so.12``; its Python wrapper also lacks the boolean setter that
``hdr`` needs. So the bundled libraries are loaded here directly with ctypes
(TBB first, globally) and called through OIDN's C API
(``include/OpenImageDenoise/oidn.h`` of OIDN 1.4).
"""

from __future__ import annotations

import ctypes
import importlib.util
import threading
from functools import lru_cache
from pathlib import Path

import numpy as np

from gevsim._validate import real_array

#: OIDN 1.4 C API constants (oidn.h).
_DEVICE_TYPE_CPU = 1
_FORMAT_FLOAT3 = 3
_ERROR_NONE = 0
_LOCK = threading.Lock()


class DenoiserUnavailable(RuntimeError):
    """OIDN could not be loaded (the ``oidn`` wheel is missing or broken)."""


@lru_cache(maxsize=1)
def _library():
    spec = importlib.util.find_spec("oidn")
    if spec is None or not spec.submodule_search_locations:
        raise DenoiserUnavailable("the 'oidn' package is not installed (pip install 'gevsim[denoise]')")
    libdir = Path(list(spec.submodule_search_locations)[0]) / "lib.linux.x64"
    tbb = sorted(libdir.glob("libtbb.so.12*"))
    lib = sorted(libdir.glob("libOpenImageDenoise.so.1*"))
    if not lib:
        raise DenoiserUnavailable(f"no libOpenImageDenoise in {libdir} (only Linux x86-64 wheels bundle it)")
    try:
        for path in tbb:
            ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
        oidn = ctypes.CDLL(str(lib[0]))
    except OSError as exc:
        raise DenoiserUnavailable(f"could not load OIDN from {libdir}: {exc}") from exc
    p, s, c = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_char_p
    for name, args, res in (
        ("oidnNewDevice", [ctypes.c_int], p), ("oidnCommitDevice", [p], None),
        ("oidnSetDevice1i", [p, c, ctypes.c_int], None),
        ("oidnGetDeviceError", [p, ctypes.POINTER(c)], ctypes.c_int), ("oidnReleaseDevice", [p], None),
        ("oidnNewFilter", [p, c], p), ("oidnSetSharedFilterImage", [p, c, p, ctypes.c_int, s, s, s, s, s], None),
        ("oidnSetFilter1b", [p, c, ctypes.c_bool], None), ("oidnCommitFilter", [p], None),
        ("oidnExecuteFilter", [p], None), ("oidnReleaseFilter", [p], None),
    ):
        fn = getattr(oidn, name)
        fn.argtypes, fn.restype = args, res
    return oidn


def available() -> str | None:
    """None when OIDN can be used, else why not (one line)."""
    try:
        _library()
    except DenoiserUnavailable as exc:
        return str(exc)
    return None


def _check(oidn, device, what: str) -> None:
    message = ctypes.c_char_p()
    code = oidn.oidnGetDeviceError(device, ctypes.byref(message))
    if code != _ERROR_NONE:
        text = message.value.decode() if message.value else f"error {code}"
        raise RuntimeError(f"OIDN {what}: {text}")


def denoise(color: np.ndarray, albedo: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Denoise an HDR image (H, W, C) with its albedo (H, W, 3 or 1) and normal (H, W, 3) guides.

    C may be 1 (luminance; denoised as grey RGB) or 3. The guides are taken
    as noise-free (``cleanAux``): render them with enough samples to
    anti-alias edges. Returns float32 (H, W, C). One thread at a time (OIDN
    uses every core itself); the result is deterministic for the same input.
    """
    color = np.asarray(color, np.float32)
    if color.ndim != 3 or color.shape[2] not in (1, 3):
        raise ValueError(f"denoise: color must be (H, W, 1 or 3), got {color.shape}")
    h, w, c = color.shape
    rgb = np.ascontiguousarray(np.repeat(color, 3, axis=2) if c == 1 else color)
    alb = np.asarray(albedo, np.float32)
    alb = np.ascontiguousarray(np.repeat(alb, 3, axis=2) if alb.shape[-1] == 1 else alb)
    nrm = np.ascontiguousarray(np.asarray(normal, np.float32))
    for name, img in (("albedo", alb), ("normal", nrm)):
        if img.shape != (h, w, 3):
            raise ValueError(f"denoise: {name} must be ({h}, {w}, 3), got {img.shape}")
    for name, img in (("color", rgb), ("albedo", alb), ("normal", nrm)):
        real_array(img, name)
    out = np.empty_like(rgb)
    oidn = _library()
    with _LOCK:
        device = oidn.oidnNewDevice(_DEVICE_TYPE_CPU)
        try:
            oidn.oidnCommitDevice(device)
            _check(oidn, device, "device")
            filt = oidn.oidnNewFilter(device, b"RT")
            try:
                for image, img in ((b"color", rgb), (b"albedo", alb), (b"normal", nrm), (b"output", out)):
                    oidn.oidnSetSharedFilterImage(filt, image, img.ctypes.data, _FORMAT_FLOAT3, w, h, 0, 0, 0)
                oidn.oidnSetFilter1b(filt, b"hdr", True)
                oidn.oidnSetFilter1b(filt, b"cleanAux", True)
                oidn.oidnCommitFilter(filt)
                oidn.oidnExecuteFilter(filt)
                _check(oidn, device, "filter")
            finally:
                oidn.oidnReleaseFilter(filt)
        finally:
            oidn.oidnReleaseDevice(device)
    return out[..., :1].copy() if c == 1 else out


def denoise_groups(mean: np.ndarray, halves: tuple[np.ndarray, np.ndarray], albedo: np.ndarray,
                   normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Denoise K group images (K, H, W, C) given with two independent half estimates of them.

    Returns ``(mean, noise)``: each group's denoised full estimate, and half
    the difference of its two denoised halves, an error sample of about the
    denoised estimate's variance (the same contract as
    :meth:`~gevsim.render.convergence.BatchAccumulator.noise`; OIDN is not
    linear, so it is an estimate of the residual noise, not of the bias).
    """
    mean = np.asarray(mean, np.float32)
    out, noise = np.empty_like(mean), np.empty_like(mean)
    for k in range(mean.shape[0]):
        out[k] = denoise(mean[k], albedo, normal)
        noise[k] = 0.5 * (denoise(halves[0][k], albedo, normal) - denoise(halves[1][k], albedo, normal))
    return out, noise
