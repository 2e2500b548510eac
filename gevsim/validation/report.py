"""``gevsim validate``: run a preset's checks and write a report with plots and a pass/fail table."""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

from gevsim.pixel.presets import SensorPreset
from gevsim.validation.checks import CHECKS, LABELS, Row, Settings, published, scene_to_chip_lux
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


#: How each label is drawn on the plots: published points a parameter was set from are filled, held-out
#: points open (they are predictions), the preset's own statements are stars.
MARKERS = {"fit": dict(marker="s", ms=6, zorder=4), "held out": dict(marker="o", ms=8, mfc="none", mew=1.6, zorder=4),
           "definition": dict(marker="D", ms=5, zorder=4), "self": dict(marker="*", ms=15, alpha=0.45, zorder=3)}
LABEL_TEXT = {"fit": "fit (a parameter was set from it)", "held out": "held out (set nothing: a prediction)",
              "definition": "definition (the preset copies it)", "self": "self (the preset's own statement)"}


def _summary(rows: list[Row]) -> list[str]:
    """One line per label: how many rows, how many pass."""
    lines = []
    for label in LABELS:
        mine = [r for r in rows if r.label == label]
        if mine:
            passed = sum(r.verdict == "pass" for r in mine)
            lines.append(f"- **{label}**: {len(mine)} rows, {passed} pass, "
                         f"{sum(r.verdict == 'fail' for r in mine)} fail ({LABEL_TEXT[label]})")
    return lines


def _sources(rows: list[Row], data: dict) -> list[str]:
    """The full reference of every source the rows name, what was taken from it and how its lux were read."""
    keys = []
    for r in rows:
        key = r.source.split(":")[0]
        if key in data.get("sources", {}) and key not in keys:
            keys.append(key)
    lines = []
    for key in keys:
        src = data["sources"][key]
        lines.append(f"- **{key}**: {src['cite']}. Taken: {src['data']}. Lux: {src['lux']}.")
    return lines


def markdown(preset: SensorPreset, rows: list[Row], settings: Settings) -> str:
    """The report: the pass/fail table with each row's label, why failing rows fail, the sources in full,
    then how the figures were made."""
    data = published()
    passed = sum(r.verdict == "pass" for r in rows)
    failed = sum(r.verdict == "fail" for r in rows)
    lines = [f"# gevsim validate: {preset.name}", "",
             f"{passed} passed, {failed} failed, {len(rows) - passed - failed} not applicable. "
             f"Preset: `{preset.source}`.", "", *_summary(rows), "",
             "| check | label | source | published | model [95 % interval] | verdict | how |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {r.check} | {r.label} | {r.source} | {r.published} | {r.model} | **{r.verdict}** | {r.note} |"
              for r in rows]
    failing = [r for r in rows if r.verdict == "fail"]
    if failing:
        lines += ["", "Why rows fail:", ""]
        lines += [f"- {r.check} ({r.label}): {r.caveat or 'no reason recorded: a defect to look into'}"
                  for r in failing]
    caveats = [r for r in rows if r.caveat and r.verdict != "fail"]
    if caveats:
        lines += ["", "What passing rows cannot tell:", ""]
        lines += [f"- {r.check}: {r.caveat}" for r in caveats]
    lines += ["", "Sources (`gevsim/validation/published.toml`):", "", *_sources(rows, data)]
    lines += ["", f"Runs: {settings.shape[1]}x{settings.shape[0]} uniform pixels, D65 light at the stated chip "
              f"(focal-plane) illuminance, {settings.duration_s:g} s per published point "
              f"({settings.curve_duration_s:g} s "
              "per curve point), a sensor that has been running (settled photoreceptor, stationary noise, random leak "
              "phases). Intervals: 95 %, from the per-pixel spread (at least Poisson); no event: [0, 3/(n T)]. "
              "Bandwidth and latency: the noise-free pixel (every pole of the chain), nominal thresholds.", "",
              "![background activity](ba_vs_lux.png)", "", "![bandwidth and latency](bandwidth_vs_lux.png)", ""]
    return "\n".join(lines)


def _points(ax, xs, ys, *, label: str, colour: str, name: str) -> None:
    if xs:
        ax.plot(xs, ys, linestyle="none", color=colour, label=f"{name}: {label}", **MARKERS[label])


def plot(preset: SensorPreset, curves: dict, out: Path) -> None:
    """ba_vs_lux.png (model curves over the published points, fit points filled and held-out points open) and
    bandwidth_vs_lux.png (the model's bandwidth and latency, the preset's statements and the published points)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = published()
    lux = curves["chip_lux"]
    floor = 1e-4
    dark_x = lux[0] / 3.0  # where 0 chip lux is drawn
    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    for key, colour, pol in (("on_hz", "tab:red", "ON"), ("off_hz", "tab:blue", "OFF")):
        v = [max(x[0], floor) for x in curves[key]]
        lo = [max(x[1], floor) for x in curves[key]]
        hi = [max(x[2], floor) for x in curves[key]]
        ax.plot(lux, v, "-", color=colour, label=f"model {pol}", lw=1.2)
        ax.fill_between(lux, lo, hi, color=colour, alpha=0.2)
    entries = [e for e in data.get("background_activity", []) if preset.name in e["sensors"]]
    colours = {"ON": "tab:red", "OFF": "tab:blue", "ON+OFF": "tab:purple"}
    for pol, colour in colours.items():
        for label in LABELS:
            pts = [e for e in entries if e["polarity"] == pol and e["label"] == label]
            _points(ax, [e["chip_lux"] if e["chip_lux"] > 0 else dark_x for e in pts],
                    [max(e["rate_hz"], floor) for e in pts], label=label, colour=colour,
                    name=f"{pol} {'/'.join(sorted({e['source'] for e in pts}))}")
    shares = [e for e in data.get("off_share", []) if preset.name in e["sensors"]]
    for label in LABELS:
        pts = [e for e in shares if e["label"] == label]
        _points(ax, [e["chip_lux"] for e in pts], [max(e["off_hz"], floor) for e in pts], label=label,
                colour="tab:blue", name=f"OFF {'/'.join(sorted({e['source'] for e in pts}))} (OFF share)")
    dark = [e for e in entries if e["chip_lux"] == 0]
    if dark:
        ax.annotate("0 lux\n(dark)", (dark_x, max(dark[0]["rate_hz"], floor) / 2.2), fontsize=7, color="0.3",
                    ha="center", va="top")
        ax.set_xlim(left=dark_x / 2.0)
    ax.set(xscale="log", yscale="log", xlabel="chip illuminance (lux)", ylabel="background activity (ev/px/s)",
           title=f"{preset.name}: DVS background activity")
    ax.text(0.01, 0.02, "filled: fit (a parameter was set there); open: held out; points at 1e-4: no event; "
            "bands: 95 % intervals", transform=ax.transAxes, fontsize=7, color="0.3")
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(out / "ba_vs_lux.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    ax.plot(lux, curves["cutoff_hz"], "-", color="tab:green", label="model: -3 dB bandwidth (Hz)")
    ax.plot(lux, [1e6 * x for x in curves["latency_s"]], "-", color="tab:orange",
            label="model: latency of a +1 ln step (us)")
    st = preset.stated
    if st.bandwidth_hz is not None:
        _points(ax, [st.bandwidth_chip_lux], [st.bandwidth_hz], label="self", colour="tab:green",
                name="stated bandwidth")
    if st.latency_s is not None:
        _points(ax, [st.latency_chip_lux], [1e6 * st.latency_s], label="self", colour="tab:orange",
                name=f"stated latency (+{st.latency_step_ln:g} ln)")
    for e in data.get("bandwidth", []):
        if preset.name in e["sensors"]:
            x = e["chip_lux"] if "chip_lux" in e else scene_to_chip_lux(
                e["scene_lux"], reflectance=e["reflectance"], f_number=e["f_number"], transmission=e["transmission"])
            _points(ax, [x], [e["cutoff_hz"]], label=e["label"], colour="tab:green", name=f"bandwidth {e['source']}")
    for e in data.get("latency", []):
        if preset.name in e["sensors"]:
            _points(ax, [e["chip_lux"]], [1e6 * e["minimum_s"]], label=e["label"], colour="tab:orange",
                    name=f"latency {e['source']}")
    ax.set(xscale="log", yscale="log", xlabel="chip illuminance (lux)", title=f"{preset.name}: bandwidth and latency")
    ax.legend(fontsize=7, loc="center right")
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
