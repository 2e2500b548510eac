"""Write a rendered scene to a folder: basis EXRs, the mixed irradiance
sequence, a JSON manifest, and (optionally) what a caller draws of the sequence
(the CLI's PNG plots: this module draws nothing).

Everything is written into a staged folder that replaces the target at the
end (:func:`gevsim.io.atomic_dir`), so a failed or interrupted run leaves no
partial output and an earlier result survives until the new one is complete.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

import gevsim
from gevsim.illumination import flicker_index, percent_flicker
from gevsim.io import MANIFEST, atomic_dir, write_exr
from gevsim.io.ownership import check_name
from gevsim.optics import Lens, cos4_map, focal_plane_irradiance, illuminance_lux, luminance
from gevsim.render.backend import VariantChoice
from gevsim.render.basis import BasisSet
from gevsim.render.manifest import SceneManifest
from gevsim.render.scene_config import resolved_config, scene_optics

#: ``plots(folder, basis, frames, times_s, mean_lux)``: draws the irradiance frames (T, H, W, C) at ``times_s``
#: and their mean illuminance (T,) into the staged output folder (so they are part of the output).
FramePlots = Callable[[Path, BasisSet, np.ndarray, list, Sequence[float]], None]


def irradiance_frames(basis: BasisSet, manifest: SceneManifest, times_s: ArrayLike, *, lens: Lens,
                      exposure_s: float | None = None, flicker: bool = True) -> np.ndarray:
    """Focal-plane irradiance (T, H, W, C), photopic-equivalent W/m^2, at ``times_s``."""
    r = manifest.render
    radiance = basis.radiance(times_s, exposure_s=exposure_s, flicker=flicker)
    cos4 = cos4_map(r.width, r.height, fov_x_deg=manifest.fov_deg)
    return focal_plane_irradiance(radiance, lens=lens, cos4=cos4).astype(np.float32)


def write_render(out: str | os.PathLike, manifest: SceneManifest, basis: BasisSet, *, variant: VariantChoice,
                 frame_rate_hz: float | None = None, exposure_s: float | None = None,
                 plots: FramePlots | None = None, progress: Callable[[int, int], None] | None = None) -> dict:
    """Write basis images, optional frames, and ``manifest.json`` to ``out``; ``plots`` (with frames) draws
    the frames into the output (:data:`FramePlots`)."""
    lens, pixel = scene_optics(manifest)
    r = manifest.render
    info = {
        "gevsim": gevsim.__version__,
        "scene": manifest.name,
        "source": manifest.source,
        "config_toml": resolved_config(manifest),
        "seed": r.seed,
        "render_noise": basis.noise_summary(),
        "render_quality_request": {"spp": r.spp if not r.targeted else None, "noise_target_ln": r.noise_target_ln,
                                   "noise_percentile": r.noise_percentile, "noise_metric": r.noise_metric,
                                   "max_spp": r.max_spp, "time_budget_s": r.time_budget_s, "sampler": r.sampler},
        "pose_quality": basis.quality,
        "width": r.width,
        "height": r.height,
        "duration_s": manifest.duration_s,
        "variant": variant.variant,
        "variant_reason": variant.reason,
        "units": {"basis": "radiance W/(m^2 sr), photopic-equivalent (683*Y = cd/m^2)",
                  "frames": "focal-plane irradiance W/m^2, photopic-equivalent (683*Y = lux)"},
        "optics": {"f_number": lens.f_number, "transmission": lens.transmission},
        "light_groups": [],
        "poses": [{"t_s": float(t)} for t in basis.times_s],
        "render_s": basis.render_s.tolist(),
    }
    for name in basis.groups:
        check_name(name, source=manifest.source, key="light_groups")  # a path part below
        group = next(g for g in manifest.light_groups if g.name == name)
        wf = group.waveform
        info["light_groups"].append({
            "name": name,
            "emitters": list(group.emitters),
            "spectrum": group.emission.spectrum,
            "waveform": repr(wf),
            "percent_flicker": float(percent_flicker(wf)),
            "flicker_index": float(flicker_index(wf)),
            "files": [f"basis/{name}/pose_{p:04d}.exr" for p in range(len(basis.times_s))],
        })
    with atomic_dir(out, kind="render", inputs=[*manifest.manifests, manifest.builder]) as stage:
        for k, name in enumerate(basis.groups):
            for p, t in enumerate(basis.times_s):
                write_exr(stage / "basis" / name / f"pose_{p:04d}.exr", basis.images[p, k],
                          metadata={"group": name, "t_s": float(t), "scene": manifest.name})
        if frame_rate_hz:
            times = np.arange(0.0, manifest.duration_s, 1.0 / frame_rate_hz)
            frames = irradiance_frames(basis, manifest, times, lens=lens, exposure_s=exposure_s)
            lux = illuminance_lux(luminance(frames))
            info["frames"] = {
                "rate_hz": float(frame_rate_hz),
                "exposure_s": exposure_s,
                "t_s": times.tolist(),
                "mean_lux": lux.reshape(len(times), -1).mean(axis=1).tolist(),
                "files": [f"frames/frame_{i:05d}.exr" for i in range(len(times))],
            }
            for i, t in enumerate(times):
                write_exr(stage / "frames" / f"frame_{i:05d}.exr", frames[i], metadata={"t_s": float(t)})
                if progress:
                    progress(i + 1, len(times))
            if plots is not None:
                plots(stage, basis, frames, times.tolist(), lux.reshape(len(times), -1).mean(axis=1))
        (stage / MANIFEST).write_text(json.dumps(info, indent=2))
    return info
