"""Checks of a scene manifest beyond types and ranges: the camera's up vector, the brightest emission, a
user's builder refusing its options, and a render that came out non-finite. Each failure is a
:class:`~gevsim.errors.ConfigError` naming the manifest and key (issue 24: bad input is one line, not a
traceback)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from gevsim.config import TomlReader
from gevsim.errors import ConfigError, GevsimError, one_line

__all__ = ["MAX_LUMINANCE_CD_M2", "brightest", "call_build", "check_rendered", "check_up"]

#: The brightest emitter a manifest may state: 1e10 cd/m^2, six times the sun's disc (1.6e9 cd/m^2). Far
#: brighter ones overflow the float32 render to inf pixels (luminance_cd_m2 = 1e300 did, with exit 0).
MAX_LUMINANCE_CD_M2 = 1e10
#: The same limit for each RGB channel of a photopic-equivalent radiance, and for an illuminance (pi times the
#: limit: a whole hemisphere of such emitters; direct sunlight gives about 1.2e5 lux).
MAX_LIMITS = {"luminance_cd_m2": MAX_LUMINANCE_CD_M2, "radiance_w_m2_sr": MAX_LUMINANCE_CD_M2 / 683.0,
              "illuminance_lux": math.pi * MAX_LUMINANCE_CD_M2}


def brightest(mode: str, value: Any, r: TomlReader, where: str) -> None:
    """Refuse an emission (a number, or an RGB triple) above :data:`MAX_LIMITS` for its ``mode``."""
    peak = max(value) if isinstance(value, tuple) else value
    if peak > MAX_LIMITS[mode]:
        unit = {"luminance_cd_m2": "cd/m^2", "radiance_w_m2_sr": "W/m^2/sr", "illuminance_lux": "lux"}[mode]
        shown = list(value) if isinstance(value, tuple) else value
        r.fail(f"{where}.{mode}", f"{shown!r} is above {MAX_LIMITS[mode]:.3g} {unit}, the brightest gevsim renders "
                                  "(six times the sun's disc, which is 1.6e9 cd/m^2)")


def check_rendered(images: np.ndarray, *, source: str, t_s: float) -> None:
    """A rendered pose must be finite: inf or NaN pixels (an emitter too bright for the float32 render, say
    one of a Mitsuba XML scene's own) are refused before they are cached or written."""
    bad = images.size - int(np.count_nonzero(np.isfinite(images)))
    if bad:
        raise ConfigError(f"the render at t = {t_s:g} s has {bad} non-finite pixel values (inf or NaN): an emitter "
                          "too bright for the float32 renderer?", source=source, key="light_groups")


def check_up(origin: Any, target: Any, up: Any, r: TomlReader, where: str) -> None:
    """The camera's up vector must be neither zero nor along the view: the camera's roll would be undefined
    (:func:`gevsim.render.trajectory.look_at` fails there)."""
    view = np.subtract(target, origin, dtype=float)
    view /= np.linalg.norm(view)
    if np.linalg.norm(up) == 0:
        r.fail(where, "must not be the zero vector")
    if np.linalg.norm(np.cross(np.divide(up, np.linalg.norm(up)), view)) < 1e-9:
        r.fail(where, f"{list(up)} is parallel to the view direction {view.tolist()} (origin to target)")


def call_build(build: Callable[[dict], Any], manifest: Any, builder: Any) -> Any:
    """``build(options)`` of a user's scene builder. Whatever exception a builder raises, refusing its options
    or failing on its own (a builder is the user's code, like a config), is a ConfigError naming the manifest,
    the builder and the exception, chained to the original (``-v`` shows its traceback); gevsim's own errors
    pass unchanged."""
    try:
        return build(dict(manifest.options))
    except GevsimError:
        raise
    except Exception as exc:
        options = f" (options {manifest.options})" if manifest.options else ""
        raise ConfigError(f"{builder.name}: build(options) raised {type(exc).__name__}: {one_line(exc)}{options}",
                          source=manifest.source, key="scene.builder") from exc
