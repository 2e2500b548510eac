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

from gevsim.render.scene import MitsubaScene, content_hash
from gevsim.render.trajectory import Pose

log = logging.getLogger("gevsim.render.basis")

#: Bump when the cached file layout or the estimator changes.
CACHE_VERSION = 2

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
