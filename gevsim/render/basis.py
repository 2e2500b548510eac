"""Light-group basis rendering with an on-disk cache, and radiance at any time.

For each pose, one image per light group is rendered from the same paths
(:mod:`gevsim.render.integrator`), in independent batches until the noise
target of the manifest's ``[render]`` table is met (:mod:`gevsim.render.convergence`)
or a fixed ``spp`` is reached. Radiance at time t is
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
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from gevsim.errors import ConfigError
from gevsim.illumination import Waveform, weights_at
from gevsim.optics import luminance
from gevsim.render.basis_cache import (  # noqa: F401  (re-exported: they lived here)
    CACHE_VERSION,
    RenderCache,
    _read_cached,
    _serves,
    cache_key,
    default_cache_dir,
    serves,
)
from gevsim.render.convergence import (
    MIN_BATCHES,
    BatchAccumulator,
    NoiseReport,
    error_percentiles,
    mixture_weights,
    needed_spp,
    next_batch_spp,
    sample_se_ln,
)
from gevsim.render.quality import RenderSettings, resolve_target
from gevsim.render.rays import PinholeGrid
from gevsim.render.scene import MitsubaScene, exact_count

log = logging.getLogger(__name__)

#: Paths traced per batch at most (memory of one JIT wavefront, ~100 B a path per group).
MAX_BATCH_PATHS = 2**22
#: ``sampling = "adaptive"``: after MIN_BATCHES, a pixel gets further batches only while its error is above
#: this fraction of the target; the stop rule (the percentile over pixels) is unchanged. At 0.5 no pixel's
#: error rises above half the target (or what uniform sampling leaves it at, where that is more), and the
#: pixels that decide the percentile get every batch, as under uniform sampling. Assumed; its effect on
#: event rates is measured in benchmarks/README.md (Moving scenes).
ADAPTIVE_STOP_FRACTION = 0.5
#: Samples per pixel of the first batches in noise-target mode.
FIRST_BATCH_SPP = 4
#: Samples per pixel of the denoiser's albedo and normal guides, and the batch index of their seed.
AUX_SPP = 64
AUX_BATCH = 2**20


def quality_request(settings: RenderSettings, mixtures: np.ndarray, target_ln: float | None) -> dict:
    """What a render must achieve: fixed ``spp``, or a resolved noise target with its limits."""
    return {"spp": settings.spp, "target_ln": target_ln, "percentile": settings.noise_percentile,
            "max_spp": settings.max_spp, "mixtures": np.asarray(mixtures, float), "floor_rel": settings.noise_floor_rel,
            "metric": settings.noise_metric, "time_budget_s": settings.time_budget_s,
            "denoise": settings.denoise, "sampling": settings.sampling}


def active_cells(active: np.ndarray, sub: int) -> np.ndarray:
    """Flat indices (row-major) of the ``sub`` x ``sub`` cells of the pixels where ``active`` (H, W) holds."""
    rows, cols = np.nonzero(active)
    dy, dx = np.divmod(np.arange(sub * sub), sub)
    width = active.shape[1] * sub
    return (((rows[:, None] * sub + dy) * width + cols[:, None] * sub + dx).ravel()).astype(np.int64)


def batch_seed(seed: int, batch: int) -> int:
    """Sampler seed of batch ``batch`` of a render with seed ``seed`` (independent streams)."""
    return int(np.random.SeedSequence([int(seed), int(batch)]).generate_state(1)[0])


def render_pose(
    scene: MitsubaScene, request: dict, *, budget_s: float | None = None, one_pass: bool | None = None,
    grid: PinholeGrid | None = None, pixels: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, NoiseReport]:
    """Render the current pose's K group images in batches until the request is met.

    Returns ``(images, noise, se_map, report)``: (K, H, W, C) mean and noise
    sample (:meth:`BatchAccumulator.noise`), the (H, W) error map
    (:meth:`BatchAccumulator.se_ln`) and a :class:`NoiseReport`. A fixed
    request renders ``spp`` in an even number of equal batches (rounded up).
    ``one_pass=False`` renders each group on its own (the scene's choice by
    default; see :meth:`MitsubaScene.render_groups`), for comparisons.
    ``grid`` renders a :class:`~gevsim.render.rays.PinholeGrid` instead of the film: images and
    noise come at its cell resolution, the error map and the request's samples per pixel
    are of its pixels (``grid.sub`` x ``grid.sub`` cells, each with 1 / sub^2 of the samples).
    ``pixels`` (flat indices into ``grid``'s cells) renders only those cells: images (K, 1, N, C), and the
    error map (1, N) of the cells.
    """
    r = scene.manifest.render
    per = 1 if grid is None else grid.sub**2  # cells a pixel's samples are spread over
    acc = BatchAccumulator(request["mixtures"], floor_rel=request["floor_rel"], metric=request["metric"],
                           cells=1 if grid is None or pixels is not None else grid.sub)
    cells = r.width * r.height if grid is None else grid.width * grid.height if pixels is None else len(pixels)
    cap = max(1, MAX_BATCH_PATHS // cells)  # samples per cell
    target = request["target_ln"]
    start = time.perf_counter()

    on_grid = {} if grid is None else {"grid": grid} if pixels is None else {"grid": grid, "pixels": pixels}
    # Per-pixel adaptive sampling: after MIN_BATCHES, only pixels whose error is above
    # ADAPTIVE_STOP_FRACTION x the target get further batches (the stop rule is unchanged).
    adaptive = request.get("sampling") == "adaptive" and target is not None and not request.get("denoise") \
        and (one_pass if one_pass is not None else scene.one_pass)
    active: np.ndarray | None = None  # the accumulator's pixels still sampled; None: all
    full_shape = (r.height, r.width) if grid is None else (1, len(pixels)) if pixels is not None \
        else (grid.height, grid.width)  # what one batch covers, in cells

    def batch(spp: int) -> None:  # samples per cell
        seed = batch_seed(r.seed, acc.batches)
        if active is None:
            images = scene.render_groups(spp=spp, seed=seed, one_pass=one_pass, **on_grid)
            acc.add(images, luminance(images), scene.sample_count(spp) * per)
            return
        if pixels is None:  # the active pixels' cells, as flat indices of the grid (or film)
            where = render = active_cells(active, 1 if grid is None else grid.sub)
        else:  # the active cells among those asked for
            where = np.flatnonzero(active.ravel())
            render = np.asarray(pixels)[where]
        part = scene.render_groups(spp=spp, seed=seed, one_pass=one_pass, grid=grid, pixels=render)
        flat = np.zeros((part.shape[0], full_shape[0] * full_shape[1], part.shape[-1]), np.float32)
        flat[:, where] = part[:, 0]
        full = flat.reshape(part.shape[0], *full_shape, part.shape[-1])
        acc.add(full, luminance(full), scene.sample_count(spp) * per, mask=active)

    if target is None:
        size, count = fixed_batches(-(-request["spp"] // per), r.sampler, cap=cap)
        if request.get("batches"):  # fewer, larger batches: each costs ~70 ms of tracing whatever its size
            count = int(request["batches"])
            size = exact_count(r.sampler, min(cap, -(-request["spp"] // (per * count))))
        for _ in range(count):
            batch(size)
        stopped = "fixed"
    else:
        stopped, ratio, have = None, None, 0  # have: samples of the pixels still sampled (the least)
        # The error over what each pixel must reach: the target, or a per-pixel map of targets
        # (``target_map``: a reuse method's budget for the cells it renders anew).
        goal = request.get("target_map", target)
        frac = float(request.get("stop_fraction", ADAPTIVE_STOP_FRACTION))
        while stopped is None:
            if active is not None:
                cap = max(1, MAX_BATCH_PATHS // (int(active.sum()) * per))
            size = next_batch_spp(have // per, first=max(1, FIRST_BATCH_SPP // per), cap=cap)
            if active is not None and ratio is not None:  # adaptive: toward the active pixels' median need,
                # at most doubling their samples a round (few, large batches: each costs ~30 ms of set-up)
                need = needed_spp(have, float(np.median(ratio[active])), frac)
                size = int(min(cap, max(size, min(have, (need - have) / 2) // per)))
                size = 4 ** int(math.log(max(size, 1), 4) + 1e-9)  # a power of 4: Dr.Jit compiles a kernel per
                # sample count (~0.5 s each), so batch sizes come from a short list that its kernel cache keeps
            size = exact_count(r.sampler, max(1, min(size, (request["max_spp"] - have) // (2 * per))))
            for _ in range(2):
                batch(size)
            elapsed = time.perf_counter() - start
            se = acc.se_ln() if acc.batches >= MIN_BATCHES else None
            ratio = None if se is None else se / goal
            if adaptive and ratio is not None:
                active = ratio > frac
            have = int(acc.pixel_spp()[active].min()) if active is not None and active.any() else acc.spp
            if se is not None and ratio is not None and (
                    np.percentile(se, request["percentile"]) <= target if np.isscalar(goal)
                    else np.percentile(ratio, request["percentile"]) <= 1.0):
                stopped = "target"
            elif have + 2 * exact_count(r.sampler, 1) * per > request["max_spp"]:
                stopped = "max_spp"
            elif budget_s is not None and elapsed * (1.0 + 2.0 * size * per / acc.spp) > budget_s:
                stopped = "time_budget"
    assert stopped is not None
    se_map = acc.se_ln()
    mean, noise, denoised = acc.mean(), acc.noise(), None
    if request.get("denoise"):
        mean, noise, denoised = denoise_pose(scene, acc, request)
    report = NoiseReport(spp=acc.spp, batches=acc.batches,
                         se_ln_percentiles=acc.percentiles(request["percentile"], se=se_map),
                         percentile=request["percentile"], target_ln=target, stopped_by=stopped,
                         spp_mean=float(acc.pixel_spp().mean()),
                         seconds=time.perf_counter() - start, denoised_se_ln=denoised)
    return mean, noise, se_map.astype(np.float32), report


def denoise_pose(scene: MitsubaScene, acc: BatchAccumulator, request: dict) -> tuple[np.ndarray, np.ndarray, dict]:
    """OIDN-denoised group images of a finished render: ``(mean, noise, error percentiles)``.

    The guides (albedo, normal) are rendered with AUX_SPP samples; the noise
    sample is half the difference of the denoised halves, and its error map
    (:func:`~gevsim.render.convergence.sample_se_ln`) gives the percentiles.
    The stop rule stays on the raw estimate, so the target is met before denoising.
    """
    from gevsim.render.denoise import denoise_groups

    albedo, normal = scene.render_aux(spp=AUX_SPP, seed=batch_seed(scene.manifest.render.seed, AUX_BATCH))
    mean, noise = denoise_groups(acc.mean(), acc.halves(), albedo, normal)
    se = sample_se_ln(acc.mixtures[:-1], luminance(mean), luminance(noise), floor_rel=acc.floor_rel,
                      metric=acc.metric)
    return mean, noise, error_percentiles(se, request["percentile"])


def fixed_batches(spp: int, sampler: str, *, cap: int) -> tuple[int, int]:
    """(batch size, even batch count) for a fixed request: at least ``spp`` samples in sizes the
    sampler takes exactly; at least MIN_BATCHES batches where possible, the fewest samples, then the
    fewest batches (never more than 4x the fewest possible)."""
    options, size = [], exact_count(sampler, cap)
    while True:
        count = max(2, 2 * -(-spp // (2 * size)))
        options.append((size, count))
        smaller = exact_count(sampler, size - 1) if size > 1 else size
        if smaller >= size:
            break
        size = smaller
    fewest_batches = options[0][1]
    eligible = [(s, c) for s, c in options if c <= 4 * max(fewest_batches, MIN_BATCHES)]
    return min(eligible, key=lambda sc: (sc[1] < MIN_BATCHES and sc[0] > 1, sc[0] * sc[1], sc[1]))


def summarize_quality(quality: list) -> dict:
    """Worst case over poses of the achieved noise (what every output records)."""
    if not quality:
        return {}
    se = {k: max(q["se_ln"][k] for q in quality) for k in quality[0]["se_ln"]}
    return {"spp_min": min(q["spp"] for q in quality), "spp_max": max(q["spp"] for q in quality),
            "se_ln": se, "percentile": quality[0]["percentile"], "target_ln": quality[0]["target_ln"],
            "reached": all(q["target_ln"] is None or q["se_ln"]["at_percentile"] <= q["target_ln"] for q in quality),
            "stopped_by": sorted({q["stopped_by"] for q in quality}),
            "denoised": any(q.get("denoised", False) for q in quality),
            "denoised_se_ln": ({k: max(q["denoised_se_ln"][k] for q in quality) for k in quality[0]["denoised_se_ln"]}
                               if quality[0].get("denoised_se_ln") else None),
            "render_s": float(sum(q["seconds"] for q in quality))}


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
    from gevsim.render import poses

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
