"""Checks of a scene manifest that go beyond types and ranges: the camera's up vector, and a user's
builder refusing its options. Each failure is a :class:`~gevsim.errors.ConfigError` naming the
manifest and key (issue 24: bad input is one line, not a traceback)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from gevsim.config import TomlReader
from gevsim.errors import ConfigError, GevsimError, one_line

__all__ = ["call_build", "check_up"]


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
    """``build(options)`` of a user's scene builder. The ValueError, TypeError or KeyError with which a
    builder refuses its options (or fails on its own) is a ConfigError naming the manifest and the builder,
    chained to the original (``-v`` shows its traceback); gevsim's own errors pass unchanged, and any other
    exception stays a traceback."""
    try:
        return build(dict(manifest.options))
    except GevsimError:
        raise
    except (ValueError, TypeError, KeyError) as exc:
        options = f" (options {manifest.options})" if manifest.options else ""
        raise ConfigError(f"{builder.name}: build(options) raised {type(exc).__name__}: {one_line(exc)}{options}",
                          source=manifest.source, key="scene.builder") from exc
