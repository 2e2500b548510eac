"""The checks of ``gevsim validate``: a preset against published measurements and against itself.

Each check returns :class:`Row` s: what was measured, the published figure and its source, the
model's figure with its 95 % interval, and a verdict (``pass``/``fail``, or ``n/a`` with the reason).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np

from gevsim.events.brightness import per_pixel_thresholds
from gevsim.events.readout import Readout
from gevsim.events.types import BRIGHTNESS_DTYPE
from gevsim.pixel.presets import SensorPreset
from gevsim.validation.measure import Rate, background_activity, cutoff_hz, step_latency_s

#: Background activity is "within 2x" of a published rate, or both are below this (ev/px/s): rates of
#: 0.001 ev/px/s take 1000 pixel-seconds per event, beyond both a bench's and a test's counting.
BA_FLOOR_HZ = 0.01
#: A self-consistency check passes when the two figures agree within this (relative) or their intervals overlap.
SELF_TOLERANCE = 0.10


@dataclass(frozen=True)
class Row:
    check: str
    source: str
    published: str
    model: str
    verdict: str  # "pass", "fail" or "n/a"
    note: str = ""


@dataclass(frozen=True)
class Settings:
    """Sizes of the runs: ``full`` for reports, ``quick`` for tests."""

    shape: tuple[int, int] = (32, 32)
    duration_s: float = 10.0
    curve_duration_s: float = 3.0

    @classmethod
    def quick(cls) -> Settings:
        return cls(shape=(16, 16), duration_s=3.0, curve_duration_s=1.0)


def published() -> dict[str, list[dict[str, Any]]]:
    """The published measurements (``published.toml``)."""
    with resources.files("gevsim.validation").joinpath("published.toml").open("rb") as f:
        return tomllib.load(f)


def _for(entries: list[dict[str, Any]], name: str) -> list[dict[str, Any]]:
    return [e for e in entries if name in e["sensors"]]


def within_2x(model: Rate, value: float) -> bool:
    """The model's rate is within 2x of a published one (by its interval), or both are below :data:`BA_FLOOR_HZ`."""
    if value <= BA_FLOOR_HZ and model.low <= BA_FLOOR_HZ:
        return True
    return model.high >= value / 2.0 and model.low <= value * 2.0


def agree(a: Rate, b: Rate) -> bool:
    """Two measurements agree within :data:`SELF_TOLERANCE` or their 95 % intervals overlap."""
    if a.low <= b.high and b.low <= a.high:
        return True
    return abs(a.value - b.value) <= SELF_TOLERANCE * max(a.value, b.value)


def _verdict(ok: bool) -> str:
    return "pass" if ok else "fail"


def check_background(preset: SensorPreset, s: Settings, data: dict) -> list[Row]:
    rows = []
    for e in _for(data.get("background_activity", []), preset.name):
        on, off = background_activity(preset, e["chip_lux"], shape=s.shape, duration_s=s.duration_s)
        for pol, model, value in (("ON", on, e["on_hz"]), ("OFF", off, e["off_hz"])):
            rows.append(Row(f"BA {pol} at {e['chip_lux']:g} lux (ev/px/s)", e["source"], f"{value:g}", str(model),
                            _verdict(within_2x(model, value)), "within 2x (or both < 0.01)"))
    for e in _for(data.get("dark_noise", []), preset.name):
        on, off = background_activity(preset, e["chip_lux"], shape=s.shape, duration_s=s.duration_s, seed=1)
        total = Rate(on.value + off.value, on.low + off.low, on.high + off.high)
        rows.append(Row(f"BA ON+OFF in the dark, {e['chip_lux']:g} lux (ev/px/s)", e["source"], f"~{e['total_hz']:g}",
                        str(total), _verdict(within_2x(total, e["total_hz"])), "within 2x"))
    return rows


def scene_to_chip_lux(scene_lux: float, *, reflectance: float, f_number: float, transmission: float) -> float:
    """Chip illuminance of a Lambertian scene: E rho T / (4 N^2) (on axis)."""
    return scene_lux * reflectance * transmission / (4.0 * f_number * f_number)


def check_bandwidth(preset: SensorPreset, s: Settings, data: dict) -> list[Row]:
    rows = []
    for e in _for(data.get("bandwidth", []), preset.name):
        lux = scene_to_chip_lux(e["scene_lux"], reflectance=e["reflectance"], f_number=e["f_number"],
                                transmission=e["transmission"])
        f = cutoff_hz(preset, lux)
        ok = abs(f / e["cutoff_hz"] - 1.0) <= e["tolerance"]
        rows.append(Row(f"bandwidth at {e['scene_lux']:g} scene lux = {lux:.3g} chip lux (Hz)", e["source"],
                        f"{e['cutoff_hz']:g} +- {100 * e['tolerance']:g} %", f"{f:.4g}", _verdict(ok),
                        f"-3 dB of the pixel output; rho {e['reflectance']}, f/{e['f_number']}, T {e['transmission']} "
                        "(assumed)"))
    for e in _for(data.get("latency", []), preset.name):
        lat = step_latency_s(preset, e["chip_lux"])
        lo, hi = e["band_s"]
        rows.append(Row(f"latency of a +1 ln step at {e['chip_lux']:g} chip lux (us)", e["source"],
                        f"minimum {1e6 * e['minimum_s']:g}, band [{1e6 * lo:g}, {1e6 * hi:g}]", f"{1e6 * lat:.3g}",
                        _verdict(lo <= lat <= hi), "noise-free, nominal threshold, plus the readout's latency_s"))
    return rows


def check_mismatch(preset: SensorPreset, s: Settings, data: dict) -> list[Row]:
    rows = []
    for e in _for(data.get("threshold_mismatch", []), preset.name):
        on, _ = per_pixel_thresholds((256, 256), preset.events, rng=np.random.default_rng(0))
        sd = float(np.std(on))
        se = sd / math.sqrt(2.0 * (on.size - 1))
        rows.append(Row("ON threshold mismatch, sigma (ln)", e["source"], f"{e['sigma_ln']:g}",
                        f"{sd:.4g} [{sd - 1.96 * se:.4g}, {sd + 1.96 * se:.4g}]",
                        _verdict(abs(sd - e["sigma_ln"]) <= max(1.96 * se, 0.05 * e["sigma_ln"])),
                        "std of 65536 drawn thresholds, within 5 %"))
    return rows


def check_readout(preset: SensorPreset, s: Settings, data: dict) -> list[Row]:
    rows = []
    for e in _for(data.get("readout", []), preset.name):
        n = 200_000
        requested = 2.0 * e["max_rate_eps"]
        ev = np.zeros(n, BRIGHTNESS_DTYPE)
        ev["t"] = np.floor(np.arange(n) * 1e6 / requested).astype(np.int64)
        ev["x"], ev["y"] = np.arange(n) % preset.width, (np.arange(n) // preset.width) % preset.height
        out = Readout(preset.readout, shape=(preset.height, preset.width)).process(ev)
        span = (out["t"][-1] - out["t"][0]) * 1e-6
        rate = (len(out) - 1) / span if span > 0 else math.inf
        rows.append(Row("readout rate under 2x overload (ev/s)", e["source"], f"{e['max_rate_eps']:.4g}",
                        f"{rate:.4g}", _verdict(rate <= 1.01 * e["max_rate_eps"] and rate >= 0.9 * e["max_rate_eps"]),
                        "a burst at twice the cap, read within 1 %"))
    return rows


def check_self(preset: SensorPreset, s: Settings, data: dict) -> list[Row]:
    """Answers must not depend on the time step or on when the run starts."""
    rows = []
    lux = 0.1
    from gevsim.validation.measure import default_step_s

    step = default_step_s(preset, lux)
    a = background_activity(preset, lux, shape=s.shape, duration_s=s.duration_s, step_s=step, seed=2)
    b = background_activity(preset, lux, shape=s.shape, duration_s=s.duration_s, step_s=step / 2, seed=2)
    for i, pol in enumerate(("ON", "OFF")):
        rows.append(Row(f"BA {pol} at {lux:g} lux: step {1e6 * step:.3g} vs {5e5 * step:.3g} us", "self",
                        str(a[i]), str(b[i]), _verdict(agree(a[i], b[i])), "within 10 % or intervals overlap"))
    r0, r1 = flicker_rates(preset, s, phase=0.0), flicker_rates(preset, s, phase=1.0 / 3.0)
    rows.append(Row("DVS rate under 100 Hz flicker, 10 lux: start at lamp phase 0 vs 1/3", "self", str(r0), str(r1),
                    _verdict(agree(r0, r1)), "within 10 % or intervals overlap"))
    return rows


def flicker_rates(preset: SensorPreset, s: Settings, *, phase: float, chip_lux: float = 10.0) -> Rate:
    """DVS events per pixel per second under a 100 Hz sinusoidal lamp (50 % modulation) over 0.2 s,
    the run starting at ``phase`` of the lamp period from a settled sensor."""
    from gevsim import _portable as pm
    from gevsim.validation.measure import photocurrent_a, pixel_counts, rate_interval, running_sensor

    shape = s.shape
    step, period = 2e-5, 0.01
    n = int(round(0.2 / step))
    per = int(round(period / step))
    i0 = photocurrent_a(preset, chip_lux)
    pr, dvs = running_sensor(preset, shape, 5)
    mid = phase * period + step * (np.arange(n) + 0.5)
    cur = i0 * (1.0 + 0.5 * pm.sin(2.0 * math.pi * 100.0 * mid))
    pr.settle(np.broadcast_to(cur[:per, None, None], (per,) + shape), np.full(per, step))
    t = step * np.arange(1, n + 1)
    ev = dvs.process(pr.process(np.broadcast_to(cur[:, None, None], (n,) + shape), t), t)
    return rate_interval(pixel_counts(ev, shape), n * step)


CHECKS = {"background activity": check_background, "bandwidth and latency": check_bandwidth,
          "threshold mismatch": check_mismatch, "readout": check_readout, "self-consistency": check_self}
