"""``gevsim validate``: run a preset's checks and write a report with plots and a pass/fail table."""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

from gevsim.pixel.presets import SensorPreset
from gevsim.validation.checks import CHECKS, Row, Settings, published
from gevsim.validation.measure import background_activity, cutoff_hz, step_latency_s

log = logging.getLogger(__name__)

#: Chip illuminances of the curves drawn under the published points.
CURVE_LUX = (0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0)


def validate(preset: SensorPreset, *, settings: Settings | None = None,
             progress: Callable[[int, int], None] | None = None) -> tuple[list[Row], dict]:
    """The check rows and the curves (background activity, bandwidth and latency vs chip lux)."""
    s = settings or Settings()
    data = published()
    rows: list[Row] = []
    total = len(CHECKS) + len(CURVE_LUX)
    for k, check in enumerate(CHECKS.values()):
        rows += check(preset, s, data)
        if progress:
            progress(k + 1, total)
    curves: dict[str, list] = {"chip_lux": list(CURVE_LUX), "on_hz": [], "off_hz": [], "cutoff_hz": [],
                               "latency_s": []}
    for k, lux in enumerate(CURVE_LUX):
        on, off = background_activity(preset, lux, shape=s.shape, duration_s=s.curve_duration_s, seed=3)
        curves["on_hz"].append([on.value, on.low, on.high])
        curves["off_hz"].append([off.value, off.low, off.high])
        curves["cutoff_hz"].append(cutoff_hz(preset, lux, tolerance=0.02))
        curves["latency_s"].append(step_latency_s(preset, lux))
        if progress:
            progress(len(CHECKS) + k + 1, total)
    return rows, curves


def markdown(preset: SensorPreset, rows: list[Row], settings: Settings) -> str:
    """The report: the pass/fail table, then how the figures were made."""
    passed = sum(r.verdict == "pass" for r in rows)
    failed = sum(r.verdict == "fail" for r in rows)
    lines = [f"# gevsim validate: {preset.name}", "",
             f"{passed} passed, {failed} failed, {len(rows) - passed - failed} not applicable. "
             f"Preset: `{preset.source}`.",
             "", "| check | source | published | model [95 % interval] | verdict | how |", "|---|---|---|---|---|---|"]
    lines += [f"| {r.check} | {r.source} | {r.published} | {r.model} | **{r.verdict}** | {r.note} |" for r in rows]
    lines += ["", f"Runs: {settings.shape[1]}x{settings.shape[0]} uniform pixels, D65 light at the stated chip "
              f"(focal-plane) illuminance, {settings.duration_s:g} s per published point "
              f"({settings.curve_duration_s:g} s "
              "per curve point), a sensor that has been running (settled photoreceptor, stationary noise, random leak "
              "phases). Intervals: 95 %, from the per-pixel spread (at least Poisson); no event: [0, 3/(n T)].",
              "Sources: `gevsim/validation/published.toml`.", "",
              "![background activity](ba_vs_lux.png)", "", "![bandwidth and latency](bandwidth_vs_lux.png)", ""]
    return "\n".join(lines)


def plot(preset: SensorPreset, curves: dict, out: Path) -> None:
    """ba_vs_lux.png (model curves over the published points) and bandwidth_vs_lux.png."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = published()
    lux = curves["chip_lux"]
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for key, colour, label in (("on_hz", "tab:red", "ON"), ("off_hz", "tab:blue", "OFF")):
        v = [max(x[0], 1e-4) for x in curves[key]]
        lo = [max(x[1], 1e-4) for x in curves[key]]
        hi = [max(x[2], 1e-4) for x in curves[key]]
        ax.plot(lux, v, "-o", color=colour, label=f"model {label}", ms=3)
        ax.fill_between(lux, lo, hi, color=colour, alpha=0.2)
        pts = [e for e in data.get("background_activity", []) if preset.name in e["sensors"]]
        ax.plot([e["chip_lux"] for e in pts], [max(e[key], 1e-4) for e in pts], "s", color=colour, mfc="none",
                ms=8, label=f"published {label} (IEBCS)")
    ax.set(xscale="log", yscale="log", xlabel="chip illuminance (lux)", ylabel="background activity (ev/px/s)",
           title=f"{preset.name}: DVS background activity")
    ax.text(0.01, 0.02, "points at 1e-4: no event (0); bands: 95 % intervals", transform=ax.transAxes, fontsize=7,
            color="0.3")
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(out / "ba_vs_lux.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot(lux, curves["cutoff_hz"], "-o", ms=3, label="-3 dB bandwidth (Hz)")
    ax.plot(lux, [1e6 * x for x in curves["latency_s"]], "-s", ms=3, label="latency of a +1 ln step (us)")
    ax.set(xscale="log", yscale="log", xlabel="chip illuminance (lux)", title=f"{preset.name}: bandwidth and latency")
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    fig.savefig(out / "bandwidth_vs_lux.png", dpi=110)
    plt.close(fig)


def check_sensor_names(presets: list[SensorPreset]) -> None:
    """Each preset's name is a folder of the report: a safe path part, and no two alike (ConfigError)."""
    from gevsim.errors import ConfigError
    from gevsim.io.ownership import check_name

    seen: dict[str, str] = {}
    for preset in presets:
        check_name(preset.name, source=preset.source, key="sensor.name")
        if preset.name in seen:
            raise ConfigError(f"two sensors are named {preset.name!r} (also {seen[preset.name]}); their reports "
                              "would share a folder", source=preset.source, key="sensor.name")
        seen[preset.name] = preset.source


def write(results: list[tuple[SensorPreset, list[Row], dict]], out: str | Path, settings: Settings) -> Path:
    """Write, per preset, ``NAME/report.md``, ``NAME/results.json`` and the plots, and a ``report.md`` that
    joins the presets' tables, into the folder ``out`` (replaced atomically)."""
    from gevsim.io.atomic import atomic_dir

    check_sensor_names([preset for preset, _, _ in results])
    with atomic_dir(out, kind="validation", inputs=[preset.source for preset, _, _ in results]) as tmp:
        tmp = Path(tmp)
        parts = []
        for preset, rows, curves in results:
            sub = tmp / preset.name
            sub.mkdir()
            text = markdown(preset, rows, settings)
            (sub / "report.md").write_text(text)
            (sub / "results.json").write_text(json.dumps({"sensor": preset.name, "rows": [asdict(r) for r in rows],
                                                          "curves": curves}, indent=1, default=float))
            plot(preset, curves, sub)
            parts.append(text.replace("](ba_vs_lux.png)", f"]({preset.name}/ba_vs_lux.png)")
                         .replace("](bandwidth_vs_lux.png)", f"]({preset.name}/bandwidth_vs_lux.png)"))
        (tmp / "report.md").write_text("\n\n".join(parts))
    return Path(out) / "report.md"
