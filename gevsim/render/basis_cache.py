"""The basis cache's keys and its test of whether a cached render serves a request.

A pose's basis images are cached as one EXR named by :func:`cache_key` (what fixes their expectation and
their random numbers); quality is recorded in the file, and :func:`serves` decides whether it meets a
request. Split from :mod:`gevsim.render.basis`, which renders and reads the files.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from pathlib import Path

import numpy as np

from gevsim.render.convergence import summarize_quality
from gevsim.render.scene import MitsubaScene, content_hash
from gevsim.render.trajectory import Pose

log = logging.getLogger("gevsim.render.basis")

#: Bump when the cached file layout or the estimator changes (3: light-vertex connection and one emitter sample
#: per light group in the one-pass integrator, issue 25: the same expectation, other random numbers and noise).
CACHE_VERSION = 3

def default_cache_dir() -> Path:
    """``$GEVSIM_CACHE``, else ``$XDG_CACHE_HOME/gevsim``, else ``~/.cache/gevsim``."""
    if os.environ.get("GEVSIM_CACHE"):
        return Path(os.environ["GEVSIM_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "gevsim"


def cache_key(scene: MitsubaScene, pose: Pose) -> str:
    """Key of a pose's basis images: what fixes their expectation and their random numbers.

    Quality (spp, noise target) is not in the key: the cached file records what
    it achieved, and a better image may serve a lesser request (:func:`serves`).
    """
    r = scene.manifest.render
    payload = {
        "scene": content_hash(scene.manifest),
        "inputs": scene.inputs_digest,  # files the builder loads (textures, meshes, helper modules)
        "pose": pose.key(),
        "groups": list(scene.manifest.group_names),
        "seed": r.seed,
        "sampler": r.sampler,
        "variant": scene.variant.variant,
        "one_pass": scene.one_pass,
        "version": CACHE_VERSION,
    }
    if r.denoise:  # a denoised render is another estimator: never mixed with raw ones
        payload["denoise"] = "oidn-1.4.3"
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:32]


def serves(meta: dict, se_map: np.ndarray | None, request: dict) -> bool:
    """Whether a cached render (its metadata and error map) meets a request (:func:`quality_request`).

    A fixed request is met by any render with at least as many samples. A
    noise-target request is met by a render with at least its ``max_spp``, or
    one whose error map (computed for the same lamp mixtures and floor) meets
    the target at the requested percentile, or one a time budget stopped when
    the request's budget is no larger.
    """
    spp = int(meta.get("spp", 0))
    if request["target_ln"] is None:
        return spp >= request["spp"]
    if spp >= request["max_spp"]:
        return True
    budget = meta.get("time_budget_s")
    if (meta.get("report", {}).get("stopped_by") == "time_budget" and budget is not None
            and request["time_budget_s"] is not None and request["time_budget_s"] <= budget):
        return True  # the same budget would stop at the same place: no better to be had
    mixtures = np.asarray(meta.get("mixtures", []), float)
    if (se_map is None or mixtures.shape != request["mixtures"].shape or meta.get("floor_rel") != request["floor_rel"]
            or meta.get("metric") != request["metric"]):
        return False
    if not np.allclose(mixtures, request["mixtures"]):
        return False
    return float(np.percentile(se_map, request["percentile"])) <= request["target_ln"]


def _serves(path: Path, cached: tuple, request: dict) -> bool:
    """:func:`serves`, with a cached record it cannot judge counted as unusable (logged, re-rendered)."""
    try:
        return serves(cached[3], cached[2], request)
    except Exception as exc:
        log.warning("cache file %s is unusable (%s); rendering again", path, exc)
        return False


class RenderCache:
    """The render cache folder: cached renders read back checked, new ones written; a folder that
    cannot be made or written to is logged once and the work goes on uncached."""

    def __init__(self, cache_dir: str | os.PathLike | None):
        from gevsim.io import sweep_stale

        self.path = Path(cache_dir) if cache_dir is not None else default_cache_dir()
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            self.writable = True
            sweep_stale(self.path, recursive=False)  # renders killed half way (other processes' live ones are locked)
        except OSError as exc:
            log.warning("render cache %s cannot be made (%s); rendering without caching", self.path,
                        exc.strerror or exc)
            self.writable = False

    def read(self, key: str, groups: tuple[str, ...], shape: tuple[int, int], request: dict) -> tuple | None:
        """(mean, noise, se_map, meta) of the cached render ``key`` when it exists, is sound and serves
        ``request``; else None. ``shape`` is the images' (H, W)."""
        path = self.path / f"{key}.exr"
        cached = _read_cached(path, groups, shape)
        return cached if cached is not None and _serves(path, cached, request) else None

    def write(self, key: str, mean: np.ndarray, noise: np.ndarray, se_map: np.ndarray, meta: dict) -> None:
        """Cache a render (every group's image and noise sample, and the error map), if the folder takes it."""
        from gevsim.errors import ConfigError
        from gevsim.io import write_exr_layers

        if not self.writable:
            return
        layers = {f"group{k}": mean[k] for k in range(len(mean))}
        layers.update({f"noise{k}": noise[k] for k in range(len(noise))})
        layers["se_ln"] = se_map
        try:
            write_exr_layers(self.path / f"{key}.exr", layers, metadata=meta)
        except (OSError, ConfigError) as exc:  # read-only or full: the run goes on, uncached
            log.warning("cannot write to the render cache %s (%s); going on without caching", self.path,
                        getattr(exc, "strerror", None) or exc)
            self.writable = False


def _read_cached(path: Path, groups: tuple[str, ...], shape: tuple[int, int]):
    """(mean, noise, se_map, meta) of a cached render, or None when absent; a file that is unreadable or not
    what :class:`RenderCache` writes (truncated, foreign, non-finite, another size) is logged and re-rendered."""
    from gevsim.io import read_exr_layers

    if not path.exists():
        return None
    try:
        layers, meta = read_exr_layers(path)
        mean = np.stack([layers[f"group{k}"] for k in range(len(groups))])
        err = np.stack([layers[f"noise{k}"] for k in range(len(groups))])
        se_map = layers["se_ln"][..., 0]
        if mean.shape[1:3] != shape or mean.shape[3] not in (1, 3) or err.shape != mean.shape \
                or se_map.shape != shape:
            raise ValueError(f"images of {mean.shape[2]}x{mean.shape[1]} px, expected {shape[1]}x{shape[0]}")
        if not (np.isfinite(mean).all() and np.isfinite(err).all()):
            raise ValueError("non-finite pixels")
        if meta.get("groups") != list(groups):
            raise ValueError(f"light groups {meta.get('groups')!r}, expected {list(groups)!r}")
        summarize_quality([meta["report"]])  # the record every output copies: complete, of the right types
        int(meta["spp"])
    except Exception as exc:  # a corrupt or foreign file is re-rendered, not fatal
        log.warning("cache file %s is unusable (%s); rendering again", path, exc)
        return None
    return mean, err, se_map, meta
