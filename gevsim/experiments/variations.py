"""Runs around a study's headline run: how far its answer moves with what was assumed, and where a design wins.

A study's ``[report] headline`` names the run its answer is about (default: the first run of the sweep).
Two optional tables add runs around it, each changing one thing (issue 35):

``[sensitivity]``
    Each number the sensor preset marks assumed (its ``[assumed.<table>]`` entries,
    :mod:`gevsim.pixel.assumed`) set to each end of its plausible range, one at a time, and ``joint``
    runs with every listed number drawn at once (uniformly within its range; a categorical one from its
    values), from the study's seed. Every run uses the headline run's noise seeds (common random
    numbers), so the change of the answer is paired. The report draws them as a tornado plot.
``[tradeoff]``
    ``settings``: design settings (sweep axes: the gradient thresholds and hysteresis, the DVS
    thresholds, ...), each a table of values applied to the headline run. The report places each
    stream's flicker- against noise-induced rate, at the pixels, and its reconstruction against the
    bandwidth the bus delivered.

```toml
[report]
headline = { scene = "office", light_scale = 1.0 }
[sensitivity]
assumed = ["noise.dc_offset_v", "events.comparator_offset_v"]   # default: all the preset's [assumed] numbers
joint = 4                      # runs with all of them drawn at once (default 0)
repeats = 3                    # default: the study's repeats (the first ones: the same seeds)
[tradeoff]
settings = [{ hysteresis_ln = 0.02 }, { thresholds_ln = [0.1, 0.2, 0.4] },
            { threshold_on_ln = 0.3, threshold_off_ln = 0.3 }]
repeats = 3
```

A sensitivity run's parameters hold ``assumed``: ``{"noise.dc_offset_v": 0.004}``, the sensor overrides by
qualified name (:func:`gevsim.pixel.presets.with_overrides`). Its jobs skip the render-noise floor and the
reconstructions (:data:`LIGHT_VARIANTS`): the tornado needs the flicker- and noise-induced rates only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from gevsim.config import TomlReader
from gevsim.errors import ConfigError, check_keys, suggest

#: The emulations of a sensitivity job (a full job adds the render-noise floor and scores reconstructions).
LIGHT_VARIANTS = ("run", "no_flicker", "ideal")
#: At most this many joint draws.
MAX_JOINT = 64
#: The keys of ``[sensitivity]`` and ``[tradeoff]``.
SENSITIVITY_KEYS = ("assumed", "joint", "repeats")
TRADEOFF_KEYS = ("settings", "repeats")


@dataclasses.dataclass(frozen=True)
class Variation:
    """One run around the headline: ``kind`` "sensitivity" (one assumed number at one end), "joint" (all of
    them drawn) or "tradeoff"; ``key`` the assumed number or the setting's text; ``end`` "low"/"high"/the
    value for a categorical one ("" for joint and trade-off runs); ``params`` the run's parameters."""

    kind: str
    key: str
    end: str
    params: dict
    repeats: int


def is_sensitivity(params: dict) -> bool:
    """Whether a run is a sensitivity run (its parameters hold ``assumed``): its jobs emulate the compared pair
    only, run :data:`LIGHT_VARIANTS` and score no reconstruction."""
    return "assumed" in params


def check_headline(report: dict, runs: list[dict], r: TomlReader) -> dict:
    """The sweep run ``[report] headline`` names (its parameters), or the first run when not given."""
    if "headline" not in report:
        return runs[0]
    want = report["headline"]
    if not isinstance(want, dict) or not want:
        r.fail("report.headline", f"expected a table of sweep values naming one run, got {want!r}")
    found = [p for p in runs if all(p.get(k, object()) == v for k, v in want.items())]
    if len(found) != 1:
        unknown = [k for k in want if k not in runs[0]]
        hint = (f"{unknown[0]!r} is not a sweep axis{suggest(unknown[0], runs[0])}" if unknown else
                f"it matches {len(found)} runs" + ("; name more axes" if found else ": no run has these values"))
        r.fail("report.headline", hint)
    return found[0]


def check_sensitivity(table: dict, preset: Any, r: TomlReader, repeats: int) -> dict:
    """``[sensitivity]``'s keys, checked against the headline sensor's preset (its ``assumed`` entries)."""
    if not table:
        return {}
    check_keys(table, SENSITIVITY_KEYS, source=r.source, where="sensitivity")
    known = dict(preset.assumed)
    if not known:
        r.fail("sensitivity", f"the sensor preset {preset.name!r} marks no number assumed ([assumed] tables)")
    keys = r.list(table, "assumed", "sensitivity.", list(known), of=str, item="a preset key such as "
                  "'noise.dc_offset_v'")
    for i, key in enumerate(keys):
        if key not in known:
            r.fail(f"sensitivity.assumed[{i}]", f"{key!r} is not an assumed number of the preset "
                                                 f"{preset.name!r}{suggest(key, known)}")
    if len(set(keys)) < len(keys):
        r.fail("sensitivity.assumed", "a key is listed twice")
    return {"assumed": keys, "joint": r.number(table, "joint", "sensitivity", 0, integer=True, minimum=0,
                                               maximum=MAX_JOINT),
            "repeats": r.number(table, "repeats", "sensitivity", repeats, positive=True, integer=True,
                                maximum=repeats)}


def check_tradeoff(table: dict, r: TomlReader, repeats: int, check_setting: Callable[[dict], None]) -> dict:
    """``[tradeoff]``'s settings, each checked as the sweep's values would be (``check_setting`` raises
    :class:`~gevsim.errors.ConfigError` for a bad one)."""
    if not table:
        return {}
    check_keys(table, TRADEOFF_KEYS, source=r.source, where="tradeoff")
    settings = r.list(table, "settings", "tradeoff.", of=dict, item="a table of sweep values")
    if not settings:
        r.fail("tradeoff.settings", "expected at least one setting, e.g. [{ hysteresis_ln = 0.02 }]")
    for i, setting in enumerate(settings):
        try:
            check_setting(setting)
        except ConfigError as exc:
            r.fail(f"tradeoff.settings[{i}]", str(exc).replace("sweep.", "", 1))
    return {"settings": settings, "repeats": r.number(table, "repeats", "tradeoff", repeats, positive=True,
                                                      integer=True, maximum=repeats)}


def setting_text(setting: dict) -> str:
    """A trade-off setting as a reader writes it: ``hysteresis_ln = 0.02``."""
    return ", ".join(f"{k} = {v}" for k, v in setting.items())


def variations(headline: dict, sensitivity: dict, tradeoff: dict, preset: Any, seed: int) -> list[Variation]:
    """Every run around ``headline``: the sensitivity runs (each assumed number at each end, then the joint
    draws), then the trade-off settings."""
    out = []
    for key in sensitivity.get("assumed", []):
        entry = preset.assumed[key]
        if entry.values:
            ends = [(str(v), v) for v in entry.values if v != entry.value]
        else:
            ends = [("low", entry.low), ("high", entry.high)]
        out += [Variation("sensitivity", key, end, {**headline, "assumed": {key: value}}, sensitivity["repeats"])
                for end, value in ends]
    for i in range(sensitivity.get("joint", 0)):
        rng = np.random.default_rng([seed, i])
        draw = {}
        for key in sensitivity["assumed"]:
            entry = preset.assumed[key]
            draw[key] = (entry.values[int(rng.integers(len(entry.values)))] if entry.values
                         else _uniform(rng, entry.low, entry.high))
        out.append(Variation("joint", f"draw {i + 1}", "", {**headline, "assumed": draw}, sensitivity["repeats"]))
    out += [Variation("tradeoff", setting_text(s), "", {**headline, **s}, tradeoff["repeats"])
            for s in tradeoff.get("settings", [])]
    return out


def _uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """A number drawn uniformly in [low, high], written with 6 significant digits (the run's parameters are
    its identity, and a config file shows them)."""
    value = low + (high - low) * float(rng.random())
    return float(f"{value:.6g}") if value != 0 and math.isfinite(value) else value
