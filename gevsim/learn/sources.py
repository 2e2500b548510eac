"""Procedural sources of light for ``gevsim dataset``: scenes made without Mitsuba, named like scenes.

A source (:class:`Source`) stands in a dataset's ``scenes`` list beside built-in scenes and manifests.
The dataset (:mod:`gevsim.experiments.dataset`) draws the source's parameters (:meth:`Source.draw`) after
everything else of a sequence, builds the driver's :class:`~gevsim.emulation.photocurrent.Setup` from them
(:meth:`Source.setup`) and marks finished sequences with the source's digest (:meth:`Source.digest`).

``planar`` (:class:`PlanarSource`): a textured plane at a random depth and tilt seen by a camera moving
in 6 DoF (:mod:`gevsim.learn.planar`, after ESIM's planar scenes: Rebecq, Gehrig & Scaramuzza, CoRL 2018),
lit by one light group ``lamp``. Its ``[dataset.planar]`` table (:class:`PlanarOptions`) sets the textures
and the ranges drawn from.
"""

from __future__ import annotations

import functools
import hashlib
import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from gevsim import _portable as pm
from gevsim.config import TomlReader
from gevsim.errors import ConfigError, check_keys, suggest
from gevsim.learn.textures import HELD_OUT, PHOTOS, PROCEDURAL

#: The least rate of the poses a source renders (Hz); the driver interpolates the light linearly between them.
POSE_RATE_HZ = 1000.0
#: Image speeds are given for this width (px); other widths scale them.
REFERENCE_WIDTH = 64


class Source(Protocol):
    group_names: tuple[str, ...]

    def options(self, table: dict, r: TomlReader, where: str) -> Any: ...

    def draw(self, rng: np.random.Generator, options: Any) -> dict: ...

    def setup(self, config: Any, params: dict) -> Any: ...

    def digest(self) -> str: ...


@dataclass(frozen=True)
class PlanarOptions:
    """``[dataset.planar]``: ``textures`` drawn from (names of :data:`~gevsim.learn.textures.PHOTOS` and
    procedural kinds), ``held_out = true`` for the held-out photographs only, and ``[low, high]`` ranges:
    ``illuminance_lux`` (chip lux of texture value 1, log-uniform), ``depth_m`` (log-uniform), ``tilt_deg``
    (the plane's, uniform), ``speed_px_s`` (image speed at 64 px width, log-uniform), ``fov_deg`` (uniform),
    ``texture_widths`` (image widths the texture spans at the plane's depth, log-uniform)."""

    textures: tuple[str, ...] = (*PHOTOS, *PROCEDURAL)
    held_out: bool = False
    illuminance_lux: tuple[float, float] = (10.0, 3000.0)
    depth_m: tuple[float, float] = (0.5, 3.0)
    tilt_deg: tuple[float, float] = (0.0, 25.0)
    speed_px_s: tuple[float, float] = (50.0, 500.0)
    fov_deg: tuple[float, float] = (45.0, 70.0)
    texture_widths: tuple[float, float] = (1.0, 8.0)


#: Each range's upper bound (and tilt's low may be 0; every other low must be positive).
_HIGH = {"illuminance_lux": 1e6, "depth_m": 1e3, "tilt_deg": 40.0, "speed_px_s": 1e4, "fov_deg": 100.0,
         "texture_widths": 1e3}


def _range(r: TomlReader, table: dict, key: str, where: str, default: tuple[float, float]) -> tuple[float, float]:
    value = table.get(key, list(default))
    high, zero = _HIGH[key], key == "tilt_deg"
    ok = (isinstance(value, list) and len(value) == 2
          and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value))
    if not ok or not (0 <= value[0] if zero else 0 < value[0]) or not value[0] <= value[1] <= high:
        r.fail(f"{where}.{key}", f"expected [low, high] with 0 {'<=' if zero else '<'} low <= high <= {high:g}, "
                                 f"got {value!r}")
    return (float(value[0]), float(value[1]))


def _texture_names(r: TomlReader, table: dict, where: str) -> tuple[str, ...]:
    value = table.get("textures", list(PlanarOptions.textures))
    allowed = (*PHOTOS, *PROCEDURAL)
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        r.fail(f"{where}.textures", f"expected a non-empty list of texture names, got {value!r}")
    for name in value:
        if name in HELD_OUT:
            r.fail(f"{where}.textures", f"{name!r} is held out: it never serves for training (held_out = true "
                                        "uses the held-out photographs)")
        if name not in allowed:
            r.fail(f"{where}.textures", f"unknown texture {name!r}{suggest(name, allowed)}; "
                                        f"choose from {', '.join(allowed)}")
    return tuple(value)


@functools.lru_cache(maxsize=1)
def _digest() -> str:
    h = hashlib.sha256()
    for name in ("sources.py", "planar.py", "textures.py"):
        h.update((Path(__file__).parent / name).read_bytes())
    return h.hexdigest()


def _srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 decoding with :mod:`gevsim._portable` (the same bits on every CPU)."""
    x = np.asarray(x, np.float64)
    power = pm.exp(2.4 * pm.log(np.maximum((x + 0.055) / 1.055, 1e-300)))
    return np.where(x <= 0.04045, x / 12.92, power)


class PlanarSource:
    """A textured plane and a 6-DoF camera (:mod:`gevsim.learn.planar`), one light group ``lamp``."""

    group_names: tuple[str, ...] = ("lamp",)

    def options(self, table: dict, r: TomlReader, where: str) -> PlanarOptions:
        """``[dataset.planar]`` checked; errors name the file and key."""
        check_keys(table, [f.name for f in fields(PlanarOptions)], source=r.source, where=where)
        held = table.get("held_out", False)
        if not isinstance(held, bool):
            r.fail(f"{where}.held_out", f"expected true or false, got {held!r}")
        if held and "textures" in table:
            r.fail(f"{where}.textures", "give textures or held_out = true, not both")
        d = PlanarOptions()
        ranges = {f.name: _range(r, table, f.name, where, getattr(d, f.name)) for f in fields(PlanarOptions)
                  if f.name not in ("textures", "held_out")}
        return PlanarOptions(textures=_texture_names(r, table, where), held_out=held, **ranges)

    def draw(self, rng: np.random.Generator, options: PlanarOptions | None) -> dict:
        """A sequence's plane, texture, camera path and light level (JSON-ready), from ``rng``."""
        from gevsim.illumination.base import log_uniform

        o = options or PlanarOptions()
        names = HELD_OUT if o.held_out else o.textures
        name = names[int(rng.integers(len(names)))]
        texture_seed = int(rng.integers(2**31))
        depth = log_uniform(rng, o.depth_m)
        tilt, azimuth = np.deg2rad(rng.uniform(*o.tilt_deg)), rng.uniform(0.0, 2.0 * np.pi)
        normal = [float(pm.sin(tilt) * pm.cos(azimuth)), float(pm.sin(tilt) * pm.sin(azimuth)), -float(pm.cos(tilt))]
        fov = float(rng.uniform(*o.fov_deg))
        widths = log_uniform(rng, o.texture_widths)
        origin = [float(x) for x in rng.uniform(0.0, 1.0, 2)]
        angle = float(rng.uniform(0.0, 2.0 * np.pi))
        # Image speed (rad/s of view): a share by translation parallel to the image, the rest by rotation.
        speed = log_uniform(rng, o.speed_px_s) / (0.5 * REFERENCE_WIDTH / float(pm.tan(np.deg2rad(fov) / 2.0)))
        share, heading = rng.uniform(0.5, 1.0), rng.uniform(0.0, 2.0 * np.pi)
        frequency = float(rng.uniform(1.0, 5.0))
        w = 2.0 * np.pi * frequency
        v = share * speed * depth
        sway = rng.uniform(-0.3, 0.3, 3) * np.array([v / w, v / w, depth / 3.0])  # z: depth +-10 %
        rock = rng.uniform(-1.0, 1.0, 3) * np.array([1.0, 1.0, 2.0]) * min((1.0 - share) * speed / w, 0.1)
        return {"texture": name, "texture_seed": texture_seed, "illuminance_lux": log_uniform(rng, o.illuminance_lux),
                "depth_m": depth, "normal": normal, "fov_deg": fov, "texture_widths": widths, "origin": origin,
                "texture_angle_rad": angle,
                "trajectory": {"velocity_m_s": [float(v * pm.cos(heading)), float(v * pm.sin(heading)), 0.0],
                               "sway_m": [float(x) for x in sway], "rock_rad": [float(x) for x in rock],
                               "roll_rad_s": float(rng.uniform(-0.5, 0.5) * (1.0 - share) * speed),
                               "frequency_hz": frequency,
                               "phase_rad": [float(x) for x in rng.uniform(0.0, 2.0 * np.pi, 6)]}}

    def frames(self, params: dict, *, width: int, height: int, t_s: np.ndarray) -> np.ndarray:
        """The plane's frames (F, H, W), linear light in [0, 1] (textures are sRGB-encoded gray)."""
        from gevsim.learn.planar import Trajectory, focal_px, render_planar
        from gevsim.learn.textures import texture

        rng = np.random.default_rng(np.random.SeedSequence([int(params["texture_seed"])]))
        tex = _srgb_to_linear(texture(params["texture"], rng))
        depth, fov = float(params["depth_m"]), float(params["fov_deg"])
        view_m = width * depth / focal_px(width, fov)  # the image's width on the plane (m), fronto-parallel
        tr = params["trajectory"]
        path = Trajectory(tuple(tr["velocity_m_s"]), tuple(tr["sway_m"]), tuple(tr["rock_rad"]),
                          float(tr["roll_rad_s"]), float(tr["frequency_hz"]), tuple(tr["phase_rad"]))
        return render_planar(tex, width=width, height=height, fov_deg=fov, t_s=t_s, depth_m=depth,
                             normal=np.array(params["normal"], np.float64), pose_at=path,
                             texel_m=float(params["texture_widths"]) * view_m / tex.shape[1],
                             origin_px=(params["origin"][0] * tex.shape[1], params["origin"][1] * tex.shape[0]),
                             angle_rad=float(params["texture_angle_rad"]))

    def setup(self, config: Any, params: dict) -> Any:
        """The driver's Setup for ``config`` (an EmulationConfig: size from ``render``, ``duration_s``, sensor,
        light scale, the ``lamp`` group's waveform) and this source's drawn ``params``."""
        return _planar_setup(self, config, params)

    def digest(self) -> str:
        """SHA-256 of the source's code (this module, the renderer and the textures)."""
        return _digest()


def _planar_setup(source: PlanarSource, config: Any, params: dict) -> Any:
    from gevsim.emulation.config import check_consistency
    from gevsim.emulation.emulators import EMULATORS
    from gevsim.emulation.frame_sensor import amperes_per_lux
    from gevsim.emulation.photocurrent import Setup
    from gevsim.illumination import from_spec
    from gevsim.pixel import load_preset
    from gevsim.pixel.presets import with_overrides
    from gevsim.render.backend import VariantChoice
    from gevsim.render.manifest import SceneManifest
    from gevsim.render.quality import RenderSettings

    if not config.duration_s:
        raise ConfigError("the planar source needs duration_s", source=config.source or None, key="duration_s")
    duration = float(config.duration_s)
    check_consistency(config, duration_s=duration)
    width, height = int(config.render.get("width", 64)), int(config.render.get("height", 48))
    for name in config.emulators:
        if EMULATORS[name].even_size and (width % 2 or height % 2):
            raise ConfigError(f"{name} (resolution compression) needs an even width and height, got "
                              f"{width}x{height}", source=config.source or None, key="render")
    preset = load_preset(config.sensor)
    if config.sensor_overrides:
        preset = with_overrides(preset, config.sensor_overrides, source=config.source, where="sensor")
    n = max(2, math.ceil(duration * POSE_RATE_HZ - 1e-9))
    t = np.arange(n + 1) * (duration / n)
    lux = float(params["illuminance_lux"]) * config.light_scale
    a_per_lux = amperes_per_lux(preset)
    current = (source.frames(params, width=width, height=height, t_s=t) * (lux * a_per_lux))[:, None]
    spec = config.group_waveform.get("lamp", {"type": "dc"})
    waveform = from_spec(spec, source=config.source or None, key="light.groups.lamp.waveform")
    manifest = SceneManifest(name="planar", source=config.source or "planar", builder=Path("planar"), options={},
                             render=RenderSettings(width=width, height=height), duration_s=duration,
                             fov_deg=float(params["fov_deg"]), camera=(), motion=(), light_groups=(),
                             raw={"planar": params})
    return Setup(manifest, preset, t, current, (waveform,), duration,
                 VariantChoice("none", "planar source: homography-warped texture, no renderer"), current_noise=None,
                 render_quality={}, chip_lux_per_a=np.array([1.0 / a_per_lux]))


#: The sources a dataset's ``scenes`` may name.
SOURCES: dict[str, Source] = {"planar": PlanarSource()}
