"""The chip's pixel footprint (issue 35, item 1).

A scene manifest's camera gives the field of view of the sensor's whole width. Emulated at a coarser
resolution than the chip (``footprint = "scene"``), each emulated pixel stands for several chip pixels
and sees their mean: it sees less scene gradient than a chip pixel, so gradient and brightness events
(and the bus share per pixel) differ from the chip's (office: a DVS/gradient flicker ratio of 17.1 at
64x48 and 25.3 at 128x96). With ``footprint = "chip"`` the emulated ``width`` x ``height`` pixels are a
centred window of the chip at its native pitch: the field of view is cut to ``width / chip width`` of the
manifest's (a pinhole's focal length in pixels is then the chip's, and each pixel sees what a chip pixel
sees), the lens and pixel optics are unchanged and the bus share follows the window's pixel count
(:func:`gevsim.events.readout.chip_share`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gevsim import _portable as pm
from gevsim.errors import ConfigError
from gevsim.pixel.presets import SensorPreset
from gevsim.render import SceneManifest


def chip_window(manifest: SceneManifest, preset: SensorPreset, *, source: str | None = None) -> SceneManifest:
    """The manifest with its field of view cut to a centred window of ``preset``'s chip at native pitch:
    tan(fov' / 2) = tan(fov / 2) x width / chip width (the manifest's ``fov_deg`` spans the chip's width)."""
    r = manifest.render
    if r.width > preset.width or r.height > preset.height:
        raise ConfigError(f"a {r.width}x{r.height} window at the chip's footprint does not fit the {preset.name} chip "
                          f"({preset.width}x{preset.height}): emulate at most the chip, or footprint = \"scene\"",
                          source=source, key="emulation.footprint")
    tan_half = float(pm.tan(np.float64(math.radians(manifest.fov_deg) / 2)))
    fov = math.degrees(2 * float(pm.atan(np.float64(tan_half * r.width / preset.width))))
    raw = dict(manifest.raw)
    raw["camera"] = {**raw.get("camera", {}), "fov_deg": fov}
    return dataclasses.replace(manifest, fov_deg=fov, raw=raw)
