"""Light-group basis rendering with an on-disk cache, and radiance at any time.

For each pose, one image per light group is rendered (other groups off, same
seed). Radiance at time t is ``sum_k w_k(t) * B_k(pose(t))``, where
``B_k(pose(t))`` blends linearly between the two poses around t.

Basis images are cached as float32 EXR files named by a hash of the scene
content, pose, light group, spp, seed and variant, so a second run renders
nothing.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import gevsim
from gevsim.illumination import Waveform, weights_at
from gevsim.io import read_exr, write_exr
from gevsim.render.scene import MitsubaScene, content_hash
from gevsim.render.trajectory import Pose

log = logging.getLogger(__name__)


def default_cache_dir() -> Path:
    """``$GEVSIM_CACHE``, else ``$XDG_CACHE_HOME/gevsim``, else ``~/.cache/gevsim``."""
    if os.environ.get("GEVSIM_CACHE"):
        return Path(os.environ["GEVSIM_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "gevsim"


def cache_key(scene: MitsubaScene, pose: Pose, group: str) -> str:
    r = scene.manifest.render
    payload = {
        "scene": content_hash(scene.manifest),
        "pose": pose.key(),
        "group": group,
        "spp": r.spp,
        "seed": r.seed,
        "variant": scene.variant.variant,
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:32]


@dataclass
class BasisSet:
    """Basis images of a scene: ``images[p, k]`` is light group k at pose p.

    Attributes
    ----------
    times_s : (P,) pose times.
    groups : names of the K light groups.
    images : float32 (P, K, H, W, C) radiance, W/(m^2 sr) photopic-equivalent.
    waveforms : the K waveforms, in group order.
    keys : (P, K) cache keys.
    render_s : (P, K) seconds each render took (0 for cache hits).
    """

    times_s: np.ndarray
    groups: tuple[str, ...]
    images: np.ndarray
    waveforms: tuple[Waveform, ...]
    keys: list = field(default_factory=list)
    render_s: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.images.shape[2:]

    def pose_blend(self, t_s: float) -> np.ndarray:
        """(K, H, W, C) basis at time ``t_s``: linear blend of the poses around it."""
        t = self.times_s
        if len(t) == 1 or t_s <= t[0]:
            return self.images[0]
        if t_s >= t[-1]:
            return self.images[-1]
        i = int(np.searchsorted(t, t_s, side="right")) - 1
        a = (t_s - t[i]) / (t[i + 1] - t[i])
        return (1.0 - a) * self.images[i] + a * self.images[i + 1]

    def radiance(self, times_s: Sequence[float], *, exposure_s: float | None = None, flicker: bool = True) -> np.ndarray:
        """Radiance (T, H, W, C) at ``times_s`` (averaged over ``exposure_s`` after each when given).

        With ``flicker=False`` every waveform is replaced by its mean (the
        counterfactual run of DESIGN.md).
        """
        waves = self.waveforms if flicker else tuple(w.constant() for w in self.waveforms)
        w = weights_at(waves, np.asarray(times_s, float), average_over_s=exposure_s)
        out = np.empty((len(w),) + self.shape, np.float32)
        for i, t in enumerate(times_s):
            centre = t + 0.5 * exposure_s if exposure_s else t
            out[i] = np.tensordot(w[i].astype(np.float32), self.pose_blend(centre), axes=1)
        return out


def render_basis(
    scene: MitsubaScene,
    *,
    cache_dir: str | os.PathLike | None = None,
    times_s: np.ndarray | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> BasisSet:
    """Render (or load from cache) every light group at every pose.

    ``progress(done, total)`` is called after each pose.
    """
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    cache.mkdir(parents=True, exist_ok=True)
    times = scene.pose_times() if times_s is None else np.asarray(times_s, float)
    groups = scene.manifest.group_names
    images, keys = [], []
    seconds = np.zeros((len(times), len(groups)))
    for p, t in enumerate(times):
        pose = scene.pose_at(float(t))
        posed = False
        row, row_keys = [], []
        for k, name in enumerate(groups):
            key = cache_key(scene, pose, name)
            path = cache / f"{key}.exr"
            if path.exists():
                img, _ = read_exr(path)
            else:
                if not posed:
                    scene.set_pose(pose)
                    posed = True
                scene.set_groups({name})
                start = time.perf_counter()
                img = scene.render()
                seconds[p, k] = time.perf_counter() - start
                meta = {"group": name, "t_s": float(t), "scene": scene.manifest.name,
                        "variant": scene.variant.variant, "gevsim": gevsim.__version__}
                write_exr(path, img, metadata=meta)
            row.append(img)
            row_keys.append(key)
        images.append(row)
        keys.append(row_keys)
        if progress:
            progress(p + 1, len(times))
    rendered = int((seconds > 0).sum())
    log.info("basis: %d poses x %d groups, %d rendered, %d from cache", len(times), len(groups), rendered,
             seconds.size - rendered)
    return BasisSet(
        times_s=times,
        groups=groups,
        images=np.asarray(images, np.float32),
        waveforms=tuple(scene.group(g).waveform for g in groups),
        keys=keys,
        render_s=seconds,
    )
