"""Light-group basis rendering with an on-disk cache, and radiance at any time.

For each pose, one image per light group is rendered from the same paths
(:mod:`gevsim.render.integrator`), in independent batches until the noise
target of the manifest's ``[render]`` table is met (:mod:`gevsim.render.convergence`)
or a fixed ``spp`` is reached (:mod:`gevsim.render.pose_render`). Radiance at time t is
``sum_k w_k(t) * B_k(pose(t))``, where ``B_k(pose(t))`` blends linearly
between the two poses around t.

Each pose is cached as one float32 EXR (every group's image, its noise sample
and the per-pixel ln error map) named by a hash of the scene content (with every
file its builder loads: :mod:`gevsim.render.inputs`), pose,
groups, seed, sampler and variant. Quality is recorded in the file, not in the
name: a cached render that meets a request serves it (:func:`serves`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from gevsim.errors import ConfigError
from gevsim.illumination import Waveform, weights_at
from gevsim.render import poses
from gevsim.render.basis_cache import (  # noqa: F401  (re-exported: they lived here)
    CACHE_VERSION,
    RenderCache,
    _read_cached,
    _serves,
    cache_key,
    default_cache_dir,
    serves,
)
from gevsim.render.convergence import mixture_weights, summarize_quality
from gevsim.render.pose_render import (  # noqa: F401  (re-exported: they lived here)
    ADAPTIVE_STOP_FRACTION,
    AUX_BATCH,
    AUX_SPP,
    FIRST_BATCH_SPP,
    MAX_BATCH_PATHS,
    active_cells,
    batch_seed,
    denoise_pose,
    fixed_batches,
    render_pose,
)
from gevsim.render.quality import RenderSettings, resolve_target
from gevsim.render.scene import MitsubaScene

log = logging.getLogger(__name__)

def quality_request(settings: RenderSettings, mixtures: np.ndarray, target_ln: float | None) -> dict:
    """What a render must achieve: fixed ``spp``, or a resolved noise target with its limits."""
    return {"spp": settings.spp, "target_ln": target_ln, "percentile": settings.noise_percentile,
            "max_spp": settings.max_spp, "mixtures": np.asarray(mixtures, float), "floor_rel": settings.noise_floor_rel,
            "metric": settings.noise_metric, "time_budget_s": settings.time_budget_s,
            "denoise": settings.denoise, "sampling": settings.sampling}


@dataclass
class BasisSet:
    """Basis images of a scene: ``images[p, k]`` is light group k at pose p.

    Attributes
    ----------
    times_s : (P,) pose times.
    groups : names of the K light groups.
    images : float32 (P, K, H, W, C) radiance, W/(m^2 sr) photopic-equivalent.
    waveforms : the K waveforms, in group order.
    keys : (P,) cache keys.
    render_s : (P,) seconds each pose's render took (0 for cache hits).
    noise : float32 (P, K, H, W, C): half the difference of two independent
        half renders, an error sample with the variance of ``images``' error
        (the render-noise floor is built from it).
    quality : per pose, the :class:`~gevsim.render.convergence.NoiseReport` as a dict.
    """

    times_s: np.ndarray
    groups: tuple[str, ...]
    images: np.ndarray
    waveforms: tuple[Waveform, ...]
    keys: list = field(default_factory=list)
    render_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    noise: np.ndarray | None = None
    quality: list = field(default_factory=list)

    def noise_summary(self) -> dict:
        """Achieved render noise over all poses: worst percentiles of the ln standard error, spp range."""
        return summarize_quality(self.quality)

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.images.shape[2:]

    def radiance(
        self, times_s: ArrayLike, *, exposure_s: float | None = None, flicker: bool = True
    ) -> np.ndarray:
        """Radiance (T, H, W, C) at ``times_s`` (averaged over ``exposure_s`` after each when given).

        With ``flicker=False`` every waveform is replaced by its mean (the
        counterfactual run of DESIGN.md).
        """
        from gevsim.illumination import mix_poses

        waves = self.waveforms if flicker else tuple(w.constant() for w in self.waveforms)
        t = np.asarray(times_s, float)
        w = weights_at(waves, t, average_over_s=exposure_s)
        centre = t + 0.5 * exposure_s if exposure_s else t  # the pose of an exposure is its middle's
        return mix_poses(self.images, self.times_s, centre, w).astype(np.float32, copy=False)


def basis_bytes(poses: int, groups: int, settings: RenderSettings) -> int:
    """Memory a basis takes while an emulation uses it: float32 images and noise samples
    (:class:`BasisSet`) and the float64 photocurrent and its noise made from them."""
    channels = 1 if settings.flavour == "mono" else 3
    return int(poses) * int(groups) * settings.width * settings.height * (2 * 4 * channels + 2 * 8)


def check_memory(poses: int, groups: int, settings: RenderSettings, *, source: str | None = None) -> None:
    """Refuse, before any rendering, a basis that would not fit in the memory this process may use."""
    from gevsim.resources import fits_memory

    fits_memory(basis_bytes(poses, groups, settings),
                what=f"{poses} poses x {groups} light groups of {settings.width}x{settings.height} px",
                source=source, key="render.max_px_per_pose" if poses > 1 else "render.width",
                hint=": render smaller, or fewer poses (a larger max_px_per_pose, a shorter duration)")


def render_basis(
    scene: MitsubaScene,
    *,
    cache_dir: str | os.PathLike | None = None,
    times_s: np.ndarray | None = None,
    progress: Callable[[int, int], None] | None = None,
    smallest_threshold_ln: float | None = None,
) -> BasisSet:
    """Render (or load from cache) every light group at every pose, to the manifest's quality.

    ``smallest_threshold_ln`` resolves ``noise_target_ln = "auto"``.
    ``progress(done, total)`` is called after each pose. A render that stops
    short of its noise target (``max_spp`` or ``time_budget_s``) logs a warning
    with the numbers.
    """
    cache = RenderCache(cache_dir)
    m = scene.manifest
    r = m.render
    times = scene.pose_times() if times_s is None else np.asarray(times_s, float)
    groups = m.group_names
    check_memory(len(times), len(groups), r, source=m.source)
    waveforms = tuple(scene.group(g).waveform for g in groups)
    mixtures = mixture_weights([_value_range(w, name) for w, name in zip(waveforms, groups)])
    request = quality_request(r, mixtures, resolve_target(r, smallest_threshold_ln))
    if r.denoise:
        from gevsim.render.denoise import available

        why = available()
        if why is not None:
            raise ConfigError(f"denoise = true, but the denoiser cannot be used: {why}", source=m.source,
                              key="render.denoise")
    method = poses.choose(scene, times)
    done = poses.METHODS[method][1](scene, times, request, cache, progress)
    quality, seconds = done.quality, done.seconds
    rendered = int((seconds > 0).sum())
    summary = summarize_quality(quality)
    log.info("basis: %d poses x %d groups (reuse: %s), %d rendered, %d from cache or reused; %d-%d spp, p%g ln "
             "error %.4g (target %s)", len(times), len(groups), method, rendered, len(times) - rendered,
             summary["spp_min"], summary["spp_max"], summary["percentile"], summary["se_ln"]["at_percentile"],
             summary["target_ln"])
    if not summary["reached"]:
        log.warning("render of %r stopped short of its noise target: p%g of the ln standard error is %.4g > %.4g "
                    "after %d spp (stopped by %s). Flicker-induced gradient events may be render noise: compare "
                    "them with the render-noise floor, or raise [render] max_spp / time_budget_s.",
                    m.name, summary["percentile"], summary["se_ln"]["at_percentile"], summary["target_ln"],
                    summary["spp_max"], ", ".join(summary["stopped_by"]))
    return BasisSet(
        times_s=times,
        groups=groups,
        images=np.asarray(done.images, np.float32),
        waveforms=waveforms,
        keys=done.keys,
        render_s=seconds,
        noise=np.asarray(done.noise, np.float32),
        quality=quality,
    )


def _value_range(waveform: Waveform, group: str) -> tuple[float, float]:
    """(min, max) of a light group's waveform: the corners of the lamp mixtures the noise target watches."""
    value_range = waveform.value_range()
    if value_range is None:
        raise ValueError(f"the waveform of light group {group!r} gives no value range for the noise target")
    return value_range
