"""One pose rendered in batches until its request is met (a fixed ``spp`` or a noise target).

:func:`render_pose` renders the current pose's light-group images in independent batches
(:mod:`gevsim.render.convergence`), on the film or on a :class:`~gevsim.render.rays.PinholeGrid`,
optionally only some of its cells and with per-pixel adaptive sampling. The basis renderer
(:mod:`gevsim.render.basis`) and the pose reuse methods (:mod:`gevsim.render.poses`) call it.
"""

from __future__ import annotations

import math
import time

import numpy as np

from gevsim.optics import luminance
from gevsim.render.convergence import (
    MIN_BATCHES,
    BatchAccumulator,
    NoiseReport,
    error_percentiles,
    needed_spp,
    next_batch_spp,
    sample_se_ln,
)
from gevsim.render.rays import PinholeGrid
from gevsim.render.scene import MitsubaScene, exact_count

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

    adaptive = request.get("sampling") == "adaptive" and target is not None and not request.get("denoise") \
        and (one_pass if one_pass is not None else scene.one_pass)
    batches = _Batches(scene, acc, grid=grid, pixels=pixels, one_pass=one_pass, per=per)
    if target is None:
        size, count = fixed_batches(-(-request["spp"] // per), r.sampler, cap=cap)
        if request.get("batches"):  # fewer, larger batches: each costs ~70 ms of tracing whatever its size
            count = int(request["batches"])
            size = exact_count(r.sampler, min(cap, -(-request["spp"] // (per * count))))
        for _ in range(count):
            batches.add(size)
        stopped = "fixed"
    else:
        stopped = _to_target(batches, request, cap=cap, adaptive=adaptive, budget_s=budget_s, start=start)
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


class _Batches:
    """Renders batches of a pose into its accumulator: every cell, or (adaptive sampling) only the cells of
    the pixels still ``active``."""

    def __init__(self, scene: MitsubaScene, acc: BatchAccumulator, *, grid: PinholeGrid | None,
                 pixels: np.ndarray | None, one_pass: bool | None, per: int):
        r = scene.manifest.render
        self.scene, self.acc, self.grid, self.pixels, self.one_pass, self.per = scene, acc, grid, pixels, one_pass, per
        self.on_grid = {} if grid is None else {"grid": grid} if pixels is None else {"grid": grid, "pixels": pixels}
        self.active: np.ndarray | None = None  # the accumulator's pixels still sampled; None: all
        self.full_shape = (r.height, r.width) if grid is None else (1, len(pixels)) if pixels is not None \
            else (grid.height, grid.width)  # what one batch covers, in cells
        self.seed = r.seed

    def add(self, spp: int) -> None:
        """Render one batch of ``spp`` samples per cell and add it."""
        scene, acc, grid, pixels, active = self.scene, self.acc, self.grid, self.pixels, self.active
        seed = batch_seed(self.seed, acc.batches)
        if active is None:
            images = scene.render_groups(spp=spp, seed=seed, one_pass=self.one_pass, **self.on_grid)
            acc.add(images, luminance(images), scene.sample_count(spp) * self.per)
            return
        if pixels is None:  # the active pixels' cells, as flat indices of the grid (or film)
            where = render = active_cells(active, 1 if grid is None else grid.sub)
        else:  # the active cells among those asked for
            where = np.flatnonzero(active.ravel())
            render = np.asarray(pixels)[where]
        part = scene.render_groups(spp=spp, seed=seed, one_pass=self.one_pass, grid=grid, pixels=render)
        h, w = self.full_shape
        flat = np.zeros((part.shape[0], h * w, part.shape[-1]), np.float32)
        flat[:, where] = part[:, 0]
        full = flat.reshape(part.shape[0], h, w, part.shape[-1])
        acc.add(full, luminance(full), scene.sample_count(spp) * self.per, mask=active)


def _to_target(batches: _Batches, request: dict, *, cap: int, adaptive: bool, budget_s: float | None,
               start: float) -> str:
    """Render pairs of batches until the error target is met (or ``max_spp`` or the time budget); returns
    what stopped it. Per-pixel adaptive sampling: after MIN_BATCHES, only pixels whose error is above
    ADAPTIVE_STOP_FRACTION x the target get further batches (the stop rule is unchanged)."""
    acc, per, sampler = batches.acc, batches.per, batches.scene.manifest.render.sampler
    target = request["target_ln"]
    stopped, ratio, have = None, None, 0  # have: samples of the pixels still sampled (the least)
    # The error over what each pixel must reach: the target, or a per-pixel map of targets
    # (``target_map``: a reuse method's budget for the cells it renders anew).
    goal = request.get("target_map", target)
    frac = float(request.get("stop_fraction", ADAPTIVE_STOP_FRACTION))
    while stopped is None:
        active = batches.active
        if active is not None:
            cap = max(1, MAX_BATCH_PATHS // (int(active.sum()) * per))
        size = next_batch_spp(have // per, first=max(1, FIRST_BATCH_SPP // per), cap=cap)
        if active is not None and ratio is not None:  # adaptive: toward the active pixels' median need,
            # at most doubling their samples a round (few, large batches: each costs ~30 ms of set-up)
            need = needed_spp(have, float(np.median(ratio[active])), frac)
            size = int(min(cap, max(size, min(have, (need - have) / 2) // per)))
            size = 4 ** int(math.log(max(size, 1), 4) + 1e-9)  # a power of 4: Dr.Jit compiles a kernel per
            # sample count (~0.5 s each), so batch sizes come from a short list that its kernel cache keeps
        size = exact_count(sampler, max(1, min(size, (request["max_spp"] - have) // (2 * per))))
        for _ in range(2):
            batches.add(size)
        elapsed = time.perf_counter() - start
        se = acc.se_ln() if acc.batches >= MIN_BATCHES else None
        ratio = None if se is None else se / goal
        if adaptive and ratio is not None:
            batches.active = active = ratio > frac
        have = int(acc.pixel_spp()[active].min()) if active is not None and active.any() else acc.spp
        if se is not None and ratio is not None and (
                np.percentile(se, request["percentile"]) <= target if np.isscalar(goal)
                else np.percentile(ratio, request["percentile"]) <= 1.0):
            stopped = "target"
        elif have + 2 * exact_count(sampler, 1) * per > request["max_spp"]:
            stopped = "max_spp"
        elif budget_s is not None and elapsed * (1.0 + 2.0 * size * per / acc.spp) > budget_s:
            stopped = "time_budget"
    assert stopped is not None
    return stopped


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
