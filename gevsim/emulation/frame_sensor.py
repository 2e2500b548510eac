"""Frame mode through the physical pixel: what a real sensor would make of a video at a light level.

The paper's frame mode (:mod:`gevsim.emulation.frames`) takes the log of the frames' gray values
directly: no photoreceptor, no noise, no bandwidth. Here the frames become light on the chip
instead, and the scene-mode sensor runs on them (photoreceptor, shot and read noise, dark current,
bandwidth, refractory period, leak, readout; :func:`gevsim.emulation.driver.run`):

- the gray values (8-bit video and images are sRGB-encoded) are decoded to linear light
  (IEC 61966-2-1, :func:`gevsim.render.shapes.srgb_to_linear`);
- linear value 1 is ``illuminance_lux`` on the chip (the focal plane), of a lamp spectrum
  (``spectrum``, CIE D65 unless given): photocurrent = value x lux x pitch^2 x fill factor x the
  pixel's responsivity (A/lm) for that spectrum (:func:`gevsim.optics.group_photocurrent_factors`
  without the lens, which chip illuminance already includes);
- between frames the light changes linearly (the frames are the poses of a one-group basis;
  :func:`gevsim.illumination.mix_poses`), as v2e interpolates (Hu, Liu & Delbruck, CVPR-W 2021);
- the emulation lasts the frames' span rounded down to whole pixel-model steps (:func:`whole_steps`):
  a 30 or 29.97 fps clip rarely spans a whole number of 20 us steps. Rounding down keeps every
  emulated instant between two real frames (the light interpolated, never held or extrapolated past
  the last frame) and drops less than one step at the end; a shortened last step would instead need
  every integrator of the pixel model (photoreceptor, noise, leak, refractory clock) to take a step of
  another length.
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path

import numpy as np

from gevsim._validate import real
from gevsim.emulation.photocurrent import Setup
from gevsim.errors import ConfigError
from gevsim.illumination import from_spec
from gevsim.optics import Lens, Pixel, group_photocurrent_factors, lamp_spectrum
from gevsim.optics.photometry import K_M_LM_PER_W
from gevsim.pixel.presets import SensorPreset
from gevsim.render.backend import VariantChoice
from gevsim.render.manifest import SceneManifest
from gevsim.render.quality import RenderSettings
from gevsim.render.shapes import srgb_to_linear
from gevsim.timebase import TimeGrid

log = logging.getLogger(__name__)

#: The brightest chip illuminance accepted (lux): 1e6 is ~10x direct sunlight imaged at f/1.
MAX_CHIP_LUX = 1e6


def amperes_per_lux(preset: SensorPreset, spectrum: str = "D65") -> float:
    """Photocurrent of one pixel of ``preset`` per lux of ``spectrum`` on the chip (A/lx)."""
    lens = Lens()
    pixel = Pixel(pitch_m=preset.pixel_pitch_m, fill_factor=preset.fill_factor, qe=preset.qe)
    factor = float(group_photocurrent_factors([lamp_spectrum(spectrum)], pixel=pixel, lens=lens)[0])
    return factor / (lens.irradiance_factor * K_M_LM_PER_W)


def check_lux(illuminance_lux: float) -> float:
    """``--illuminance-lux`` as a float in (0, :data:`MAX_CHIP_LUX`]; FieldError naming the flag otherwise."""
    return real(illuminance_lux, "--illuminance-lux", low=0.0, low_open=True, high=MAX_CHIP_LUX)


def whole_steps(span_s: float, step_s: float, *, source: str | os.PathLike) -> float:
    """The frames' span ``span_s`` rounded down to a whole number of steps of ``step_s`` (at least two: the
    time grid needs a step shorter than the duration); said in an INFO line when it changes by more than
    the grid's own tolerance (1e-6 of a step per step)."""
    exact = span_s / step_s
    n = math.floor(exact * (1 + 1e-9))  # a span that is a whole number of steps up to rounding stays whole
    if n < 2:
        raise ConfigError(f"the frames span {span_s * 1e6:.6g} us, less than two steps of the pixel model "
                          f"({step_s * 1e6:g} us each): give frames further apart (a lower --fps)",
                          source=str(source))
    if abs(exact - n) <= 1e-6 * n:
        return span_s
    duration = n * step_s
    log.info("%s: the frames span %.9g s, %.6g steps of %g us; emulating %d whole steps (%.9g s), the light "
             "interpolated between the frames as everywhere else", source, span_s, exact, step_s * 1e6, n, duration)
    return duration


def frame_setup(frames: np.ndarray, t_s: np.ndarray, *, preset: SensorPreset, illuminance_lux: float,
                source: str | os.PathLike, spectrum: str = "D65", step_s: float = TimeGrid.step_s) -> Setup:
    """A driver :class:`~gevsim.emulation.photocurrent.Setup` whose light is the frames (F, H, W) in [0, 1]
    (sRGB-encoded gray) at times ``t_s``, value 1 being ``illuminance_lux`` on the chip, lasting the
    frames' span rounded down to whole steps of ``step_s`` (:func:`whole_steps`)."""
    lux = check_lux(illuminance_lux)
    if len(t_s) < 2:
        raise ConfigError(f"frame mode needs at least two frames, got {len(t_s)}", source=str(source))
    frames = np.asarray(frames, np.float64)
    t = np.asarray(t_s, np.float64) - float(t_s[0])
    duration = whole_steps(float(t[-1]), step_s, source=source)
    a_per_lux = amperes_per_lux(preset, spectrum)
    current = (srgb_to_linear(frames) * lux * a_per_lux)[:, None]  # (F, 1, H, W): one "light group"
    h, w = frames.shape[1:]
    raw = {"frames": {"source": str(source), "count": int(len(frames)), "illuminance_lux": lux,
                      "spectrum": spectrum, "decoding": "sRGB (IEC 61966-2-1)"}}
    manifest = SceneManifest(name=Path(source).name or "frames", source=str(source), builder=Path(source),
                             options={}, render=RenderSettings(width=int(w), height=int(h)),
                             duration_s=duration, fov_deg=60.0, camera=(), motion=(), light_groups=(), raw=raw)
    return Setup(manifest, preset, t, current, (from_spec({"type": "dc"}),), duration,
                 VariantChoice("none", "frame mode: frames, no renderer"), current_noise=None,
                 render_quality={}, chip_lux_per_a=np.array([1.0 / a_per_lux]))
