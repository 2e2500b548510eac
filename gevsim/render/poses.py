"""How a scene's poses get their basis images: a registry of reuse methods.

``[render] reuse`` names one (:data:`gevsim.render.quality.REUSE`):

- ``"none"``: every pose is rendered alone to the noise target (:func:`render_each`).
- ``"rotation"``: a camera turning about a fixed centre, nothing else moving: the
  poses are resamplings of one wider render (:func:`render_rotation`,
  :mod:`gevsim.render.rotation`).
- ``"auto"``: the first method that applies, in the order of :data:`METHODS`
  (``"none"`` always does; it is tried last).

Each method returns a :class:`PoseImages` for the poses' times; every image is
cached (:class:`~gevsim.render.basis_cache.RenderCache`) under a key of what
fixes it.
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

import gevsim
from gevsim.errors import ConfigError
from gevsim.render import pose_render, rotation
from gevsim.render.basis_cache import CACHE_VERSION, RenderCache, cache_key
from gevsim.render.convergence import error_percentiles
from gevsim.render.manifest_checks import check_rendered
from gevsim.render.scene import MitsubaScene, content_hash

log = logging.getLogger("gevsim.render.basis")

Progress = Callable[[int, int], None] | None


@dataclass
class PoseImages:
    """Per pose: (K, H, W, C) images and noise samples, cache keys, quality records and render seconds."""

    images: list
    noise: list
    keys: list
    quality: list
    seconds: np.ndarray


def _meta(scene: MitsubaScene, request: dict, report: dict, t_s: float, **extra) -> dict:
    r = scene.manifest.render
    return {"groups": list(scene.manifest.group_names), "t_s": float(t_s), "scene": scene.manifest.name,
            "variant": scene.variant.variant, "gevsim": gevsim.__version__, "spp": report["spp"], "report": report,
            "mixtures": request["mixtures"].tolist(), "floor_rel": request["floor_rel"],
            "metric": request["metric"], "time_budget_s": request["time_budget_s"], "sampler": r.sampler,
            "one_pass": scene.one_pass, "denoised": bool(r.denoise), **extra}


def _budget(request: dict, started: float, left: int) -> float | None:
    """Seconds a render may take: an equal share of what is left of the time budget."""
    if request["time_budget_s"] is None:
        return None
    return max(0.0, request["time_budget_s"] - (time.perf_counter() - started)) / max(left, 1)


def render_each(scene: MitsubaScene, times: np.ndarray, request: dict, cache: RenderCache,
                progress: Progress) -> PoseImages:
    """Every pose rendered alone (or read from the cache) to the request."""
    m = scene.manifest
    out = PoseImages([], [], [], [], np.zeros(len(times)))
    started = time.perf_counter()
    for p, t in enumerate(times):
        pose = scene.pose_at(float(t))
        key = cache_key(scene, pose)
        cached = cache.read(key, m.group_names, (m.render.height, m.render.width), request)
        if cached is not None:
            mean, err, _, meta = cached
            out.quality.append(meta["report"])
        else:
            scene.set_pose(pose)
            mean, err, se_map, report = pose_render.render_pose(scene, request,
                                                          budget_s=_budget(request, started, len(times) - p))
            check_rendered(mean, source=m.source, t_s=float(t))
            out.seconds[p] = report.seconds
            out.quality.append(report.as_dict())
            cache.write(key, mean, err, se_map, _meta(scene, request, report.as_dict(), t))
        out.images.append(mean)
        out.noise.append(err)
        out.keys.append(key)
        if progress:
            progress(p + 1, len(times))
    return out


def rotation_applies(scene: MitsubaScene, times: np.ndarray) -> str | None:
    """Why rotation reuse cannot render these poses, or None when it can."""
    m = scene.manifest
    why = _jit_single_view(scene, times)
    if why is not None:
        return why
    cameras = [scene.pose_at(float(t)).camera for t in times]
    if not rotation.same_centre(cameras):
        return "the camera moves (only a camera turning about a fixed centre is a resampling)"
    try:
        for seg in rotation.plan(cameras, fov_deg=m.fov_deg, width=m.render.width, height=m.render.height):
            for p in seg.poses:
                rotation.footprints(seg.grid, cameras[p], width=m.render.width, height=m.render.height)
    except ValueError as exc:
        return str(exc)
    return None


def _grid_key(scene: MitsubaScene, grid, method: str = "rotation") -> str:
    """Cache key of a reference window: what :func:`~gevsim.render.basis_cache.cache_key` holds for a pose
    (the estimator's version included), with the grid in place of the pose."""
    r = scene.manifest.render
    payload = {"scene": content_hash(scene.manifest), "inputs": scene.inputs_digest, "grid": grid.key(),
               "groups": list(scene.manifest.group_names), "seed": r.seed, "sampler": r.sampler,
               "variant": scene.variant.variant, "method": method, "version": rotation.CACHE_VERSION,
               "estimator": CACHE_VERSION}
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:32]


def render_rotation(scene: MitsubaScene, times: np.ndarray, request: dict, cache: RenderCache,
                    progress: Progress) -> PoseImages:
    """Poses of a camera turning about a fixed centre, resampled from one render per segment
    (:func:`gevsim.render.rotation.plan`): its seconds are booked on the segment's first pose."""
    m, r = scene.manifest, scene.manifest.render
    cameras = [scene.pose_at(float(t)).camera for t in times]
    segments = rotation.plan(cameras, fov_deg=m.fov_deg, width=r.width, height=r.height)
    out = PoseImages([], [], [], [], np.zeros(len(times)))
    started = time.perf_counter()
    done = 0
    for i, seg in enumerate(segments):
        g = seg.grid
        key = _grid_key(scene, g)
        ref = seg.poses[(len(seg.poses) - 1) // 2]
        mean, err, se_map, report = _window_render(scene, g, key, times[ref], request, cache,
                                                   _budget(request, started, len(segments) - i), out, seg.poses[0])
        for p in seg.poses:
            rect = rotation.footprints(g, cameras[p], width=r.width, height=r.height)
            out.images.append(rotation.box_resample(mean, rect))
            out.noise.append(rotation.box_resample(err, rect))
            se = rotation.pixel_error(se_map, g, rect)
            out.quality.append({**report, "se_ln": {**report["se_ln"],
                                                    **error_percentiles(se, request["percentile"])},
                                "seconds": out.seconds[p], "reuse": "rotation", "reference_t_s": float(times[ref])})
            out.keys.append(f"{key}/{p - seg.poses[0]}")
            done += 1
            if progress:
                progress(done, len(times))
    log.info("rotation reuse: %d poses from %d render(s) of %s cells", len(times), len(segments),
             ", ".join(f"{s.grid.width}x{s.grid.height}" for s in segments))
    return out


def parallax_applies(scene: MitsubaScene, times: np.ndarray) -> str | None:
    """Why parallax reuse cannot render these poses, or None when it can."""
    from gevsim.render import parallax

    why = _jit_single_view(scene, times)
    if why is not None:
        return why
    if rotation.same_centre([scene.pose_at(float(t)).camera for t in times]):
        return "the camera does not move (rotation reuse serves a turning camera)"
    return parallax.view_independent(scene)


def _jit_single_view(scene: MitsubaScene, times: np.ndarray) -> str | None:
    """What every reuse method needs: several poses, nothing but the camera moving, a one-pass variant, no denoiser."""
    m = scene.manifest
    if len(times) < 2:
        return "one pose"
    if m.motion:
        return "objects move"
    if not scene.one_pass or "spectral" in scene.variant.variant:
        return f"the {scene.variant.variant} variant has no one-pass integrator"
    if m.render.denoise:
        return "denoise = true (the denoiser works on whole images of one pose)"
    return None


def render_parallax(scene: MitsubaScene, times: np.ndarray, request: dict, cache: RenderCache,
                    progress: Progress) -> PoseImages:
    """Poses of a camera moving through a static, view-independent scene: each pixel reprojected from
    its segment's reference render where that is exact, rendered anew where not
    (:mod:`gevsim.render.parallax`)."""
    from gevsim.render import parallax

    m, r = scene.manifest, scene.manifest.render
    cameras = [scene.pose_at(float(t)).camera for t in times]
    segments = parallax.plan(scene, cameras, sub=rotation.SUB)
    out = PoseImages([], [], [], [], np.zeros(len(times)))
    started = time.perf_counter()
    done = 0
    for i, seg in enumerate(segments):
        g = seg.grid
        key = _grid_key(scene, g, "parallax")
        ref = seg.poses[(len(seg.poses) - 1) // 2]
        window = None
        for p in seg.poses:
            pose = scene.pose_at(float(times[p]))
            pose_key = hashlib.sha256(json.dumps([key, pose.key()], sort_keys=True).encode()).hexdigest()[:32]
            cached = cache.read(pose_key, m.group_names, (r.height, r.width), request)
            if cached is not None:
                images, noise, _, meta = cached
                out.quality.append(meta["report"])
            else:
                if window is None:
                    window = _window_render(scene, g, key, times[ref], request, cache,
                                            _budget(request, started, len(segments) - i), out, seg.poses[0])
                tick = time.perf_counter()
                images, noise, se, ok = _parallax_pose(scene, pose, g, window, request)
                out.seconds[p] += time.perf_counter() - tick
                quality = {**window[3], "seconds": float(out.seconds[p]), "reuse": "parallax",
                           "reused_fraction": float(ok.mean()), "reference_t_s": float(times[ref]),
                           "se_ln": {**window[3]["se_ln"], **error_percentiles(se, request["percentile"])}}
                out.quality.append(quality)
                cache.write(pose_key, images, noise, se, _meta(scene, request, quality, times[p], reuse="parallax"))
            out.images.append(images)
            out.noise.append(noise)
            out.keys.append(pose_key)
            done += 1
            if progress:
                progress(done, len(times))
    fractions = [q.get("reused_fraction", 1.0) for q in out.quality]
    log.info("parallax reuse: %d poses from %d reference render(s); %.1f %% of pixels reused (%.1f-%.1f %% a pose)",
             len(times), len(segments), 100 * np.mean(fractions), 100 * min(fractions), 100 * max(fractions))
    return out


def _parallax_pose(scene: MitsubaScene, pose, g, window: tuple, request: dict) -> tuple:
    """(images, noise, pixel error map, reused cells) of one pose: each of its pixels' ``g.sub`` x ``g.sub``
    cells reprojected from the window, or rendered anew at the window's density of samples (the window's
    samples per pixel spread over its cells) when it cannot be; a pixel is the mean of its cells."""
    from gevsim.render import parallax
    from gevsim.render.rays import PinholeGrid, focal_px

    m, r = scene.manifest, scene.manifest.render
    s, (h, w) = g.sub, (r.height, r.width)
    mean, err, se_map, report = window
    rect, ok = parallax.reproject(scene, g, pose.camera, sub=s)
    both = rotation.box_resample(np.concatenate([mean, err]), rect)  # one pass over the overlaps for both
    cells, cell_noise = both[:len(mean)], both[len(mean):]
    var = rotation.box_resample(np.repeat(np.repeat(np.square(se_map.astype(np.float64)) * s * s, s, axis=0), s,
                                          axis=1)[None, ..., None], rect, power=2)[0, ..., 0].astype(np.float64)
    todo = np.flatnonzero(~ok)
    if todo.size:
        scene.set_pose(pose)
        grid = PinholeGrid(pose.camera, focal_px(m.fov_deg, w), w / 2, h / 2, 0.0, 0.0, w * s, h * s, s)
        if request.get("sampling") == "adaptive" and request["target_ln"] is not None:
            ask = {**request, "target_ln": request["target_ln"] * s, "stop_fraction": 1.0,
                   "target_map": cell_targets(var, ok, request["target_ln"], s).ravel()[None, todo]}
        else:
            # The window's density of samples, in 4 batches (a noise sample and 3 degrees of freedom for the
            # reported error; the default 8 or more cost ~70 ms of tracing each for a few thousand cells).
            ask = {**request, "spp": int(report["spp"]), "target_ln": None, "batches": 4}
        sub_mean, sub_err, sub_se, _ = pose_render.render_pose(scene, ask, grid=grid, pixels=todo)
        rows, cols = np.divmod(todo, w * s)
        cells[:, rows, cols], cell_noise[:, rows, cols] = sub_mean[:, 0], sub_err[:, 0]
        var[rows, cols] = np.square(sub_se[0].astype(np.float64))

    def pixels(a: np.ndarray) -> np.ndarray:
        return a.reshape(a.shape[0], h, s, w, s, a.shape[-1]).mean(axis=(2, 4))

    se = np.sqrt(var.reshape(h, s, w, s).sum(axis=(1, 3)) / s**4).astype(np.float32)
    return pixels(cells).astype(np.float32), pixels(cell_noise).astype(np.float32), se, ok


def cell_targets(var: np.ndarray, ok: np.ndarray, target: float, s: int) -> np.ndarray:
    """(H s, W s) ln error each cell rendered anew may have so that its pixel meets ``target``: what the
    pixel's reused cells (variances ``var``, reused where ``ok``) leave of its budget (a pixel's variance
    is its cells' sum / s^4), shared equally by its new cells, but never less than s x the target (what
    each cell of a pixel of s^2 new cells needs): where the reused cells leave less than that, the pixel
    may end above the target, as it may under uniform sampling."""
    h, w = ok.shape[0] // s, ok.shape[1] // s
    reused = np.where(ok, var, 0.0).reshape(h, s, w, s).sum(axis=(1, 3))
    fresh = (~ok).reshape(h, s, w, s).sum(axis=(1, 3))
    left = (target * s * s) ** 2 - reused
    each = np.where(fresh > 0, left / np.maximum(fresh, 1), 0.0)
    each = np.maximum(each, (target * s) ** 2)  # never stricter than s x the target for a cell
    return np.repeat(np.repeat(np.sqrt(each), s, axis=0), s, axis=1)


def _window_render(scene, g, key, t_ref, request, cache, budget, out, first) -> tuple:
    """The reference window's (mean, noise, pixel error map, report dict), from the cache or rendered.
    EXR layers share one size: the pixels' error map is stored at cell resolution, each value repeated."""
    m = scene.manifest
    cached = cache.read(key, m.group_names, (g.height, g.width), request)
    if cached is not None:
        mean, err, se_cells, meta = cached
        return mean, err, se_cells[::g.sub, ::g.sub], meta["report"]
    scene.set_pose(scene.pose_at(float(t_ref)))
    mean, err, se_map, noise_report = pose_render.render_pose(scene, request, budget_s=budget, grid=g)
    check_rendered(mean, source=m.source, t_s=float(t_ref))
    report = noise_report.as_dict()
    out.seconds[first] += noise_report.seconds
    se_cells = np.repeat(np.repeat(se_map, g.sub, axis=0), g.sub, axis=1)
    cache.write(key, mean, err, se_cells, _meta(scene, request, report, t_ref, reuse="window", grid=g.key()))
    return mean, err, se_map, report


#: Reuse methods in the order ``"auto"`` tries them: name -> (why it does not apply or None, renderer).
METHODS: dict[str, tuple[Callable[[MitsubaScene, np.ndarray], str | None], Callable[..., PoseImages]]] = {
    "rotation": (rotation_applies, render_rotation),
    "parallax": (parallax_applies, render_parallax),
    "none": (lambda scene, times: None, render_each),
}


def choose(scene: MitsubaScene, times: np.ndarray) -> str:
    """The reuse method for these poses: ``[render] reuse``, or the first that applies for ``"auto"``.
    A named method that does not apply is a ConfigError saying why."""
    wanted = scene.manifest.render.reuse
    if wanted != "auto":
        why = METHODS[wanted][0](scene, times)
        if why is not None:
            raise ConfigError(f"reuse = {wanted!r} cannot render this scene: {why}", source=scene.manifest.source,
                              key="render.reuse")
        return wanted
    return next(name for name, (applies, _) in METHODS.items() if applies(scene, times) is None)
