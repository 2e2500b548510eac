"""Studies: sweeps of emulation parameters, each run repeated with R noise seeds and its counterfactuals.

A study config names a base emulation and sweep axes; every combination is a
run. Each run is repeated with ``repeats`` noise seeds, and each repeat is
emulated four times with its seed (DESIGN.md, Counterfactual runs; common random
numbers): as is, with every lamp waveform replaced by its mean, with an ideal
pixel as well, and the render-noise floor (ideal pixel, lamps at their mean, the
render's noise redrawn at the lamp frequency:
:func:`gevsim.emulation.driver.render_noise_floor`). Flicker-induced events are
the events of the run minus those without flicker; noise-induced events those
without flicker minus those of the ideal pixel; the render-noise floor the floor
run's events minus the ideal run's. Their means over the repeats come with 95 %
intervals, beside a phase-locked estimate that needs no subtraction
(:mod:`gevsim.experiments.aggregate`). Reconstructions of the run are scored
against the flicker-free reference.

Each (run, repeat) is one job (:mod:`gevsim.experiments.repeat`), run here or by
an executor (:mod:`gevsim.experiments.executors`) from
:func:`gevsim.experiments.study_run.run_study`; each writes
``runs/<id>/r<k>.json`` last and atomically, so a rerun skips finished jobs and
interrupted studies resume; :func:`run_id` says what makes a rerun compute a run anew.

```toml
[study]
name = "flicker"
scene = "office"
sensor = "davis346"
emulators = ["dvs", "gradient", "gradient_rc", "csdvs"]
flicker_group = "ceiling"      # the swept light group, or a table: { office = "ceiling", street_night = "street_lamp" }
duration_s = 0.02
step_s = 2e-5
frame_rate_hz = 500.0
seed = 1                       # repeat r uses noise seed seed + r
repeats = 3                    # noise seeds per run (default 3); more later reuses the finished ones
methods = ["dct", "direct"]    # reconstructions to score (gradient: dct/sor[_rc]; brightness: direct/...)
[study.render]
width = 64
height = 48
spp = 4
[sweep]                        # axes; the runs are their cartesian product
frequency_hz = [100.0, 300.0, 1000.0]
waveform = ["pwm", "sinusoid"] # native (the scene's own), pwm, sinusoid, fluorescent, sodium_hid, incandescent, dc
flicker_scale = [1.0]          # radiance factor of the flickering group (its share of the light)
scene = ["office", "office_pan"]
sensor = ["davis346"]
thresholds_ln = [[0.05, 0.1, 0.2]]
hysteresis_ln = [0.0, 0.02]    # gradient comparator hysteresis (0: the paper)
window = [[64, 48], [96, 72]]  # rendered width x height (with footprint = "chip": a window of the chip); also
                               # duty, modulation; docs/config.md lists every axis and [sensitivity], [tradeoff]
[report]
x = "frequency_hz"
lines = "waveform"
```
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from pathlib import Path

from gevsim import __version__
from gevsim._validate import FieldError
from gevsim.config import TomlReader, load_table, resolve_relative
from gevsim.emulation.config import MAX_LIGHT_SCALE, EmulationConfig, check_footprint
from gevsim.emulation.emulators import EMULATORS, HEADLINE, PARAMS, check_emulator_list
from gevsim.errors import ConfigError, check_keys, suggest
from gevsim.evaluation.methods import METHODS, check_method
from gevsim.experiments import variations as around
from gevsim.illumination.base import MAX_FREQUENCY_HZ
from gevsim.illumination.spec import SWEPT_WAVEFORMS, swept_spec
from gevsim.pixel import load_preset
from gevsim.render.manifest import check_render_overrides
from gevsim.resources import MAX_REPEATS, MAX_STUDY_RUNS, at_most
from gevsim.timebase import TimeGrid

STUDY_KEYS = ("name", "description", "scene", "sensor", "emulators", "flicker_group", "duration_s", "step_s",
              "frame_rate_hz", "seed", "methods", "render", "chunk_steps", "repeats", "footprint")
#: Sweep axes that override a sensor preset parameter (see gevsim.pixel.presets.with_overrides).
SENSOR_AXES = ("threshold_mismatch_ln", "cutoff_hz", "max_cutoff_hz", "dark_current_a", "read_noise_v",
               "pixel_pitch_m", "fill_factor", "refractory_s", "threshold_on_ln", "threshold_off_ln")
AXES = ("frequency_hz", "waveform", "duty", "modulation", "light_scale", "flicker_scale", "scene", "sensor",
        "thresholds_ln", "hysteresis_ln", "window") + SENSOR_AXES
#: A study config's tables, and the keys of its ``[report]``.
TABLES = ("study", "sweep", "report", "sensitivity", "tradeoff")
REPORT_KEYS = ("x", "lines", "headline")
#: A study's time grid unless its [study] table says otherwise: 20 ms in 20 us steps, frames at 500 Hz.
STUDY_TIME = TimeGrid(duration_s=0.02, step_s=2e-5, frame_rate_hz=500.0)
#: Repeats (noise seeds) per run when ``[study] repeats`` is not given.
DEFAULT_REPEATS = 3
#: The sweep's waveform choice that keeps the scene's own lamp.
NATIVE = "native"
#: The sweep's waveform choices: the scene's own, or a lamp type of the registry that studies sweep.
WAVEFORMS = (NATIVE, *SWEPT_WAVEFORMS)


@dataclasses.dataclass(frozen=True)
class Study:
    name: str
    base: dict
    axes: dict
    report: dict
    source: str
    text: str
    description: str = ""
    headline: dict = dataclasses.field(default_factory=dict)  # the run the answer is about ([report] headline)
    sensitivity: dict = dataclasses.field(default_factory=dict)  # checked [sensitivity] (gevsim.experiments.variations)
    tradeoff: dict = dataclasses.field(default_factory=dict)  # checked [tradeoff]

    def runs(self) -> list[dict]:
        """Every combination of the sweep axes (in config order), as parameter dicts."""
        names = list(self.axes)
        return [dict(zip(names, values)) for values in itertools.product(*(self.axes[n] for n in names))]

    def variations(self) -> list[around.Variation]:
        """The runs around the headline run: ``[sensitivity]`` and ``[tradeoff]``
        (:func:`gevsim.experiments.variations.variations`)."""
        if not (self.sensitivity or self.tradeoff):
            return []
        preset, seed = load_preset(self.headline.get("sensor", self.base["sensor"])), int(self.base["seed"])
        return [dataclasses.replace(v, repeats=min(v.repeats, self.base["repeats"]))  # --repeats may lower it
                for v in around.variations(self.headline, self.sensitivity, self.tradeoff, preset, seed)]


def load_study(path: str | Path) -> Study:
    """Read and validate a study config; errors name the file and key. Relative ``.toml`` paths (sensor
    presets, scene manifests) are taken from the study file's folder, as datasets do, not from the working
    directory: two folders' studies naming ``my.toml`` name different presets."""
    path = Path(path)
    raw, r = load_table(path, what="study config", tables=TABLES)
    st = r.table(raw, "study")
    emulators = _check_study_table(st, r)
    sweep = r.table(raw, "sweep")
    _check_sweep(sweep, r)
    if isinstance(sweep.get("sensor"), list):
        sweep["sensor"] = [resolve_relative(v, path.parent) for v in sweep["sensor"]]
    for method in r.list(st, "methods", "study.", ["dct", "direct"]):
        try:
            needs = check_method(method).emulator
        except ValueError as exc:
            r.fail("study.methods", str(exc))
        if needs not in emulators:
            r.fail("study.methods", f"method {method!r} needs the {needs!r} emulator in study.emulators")
    check_render_overrides(r.table(st, "render", "study."), r, "study.render")
    rep = r.table(raw, "report")
    check_keys(rep, REPORT_KEYS, source=r.source, where="report")
    for key in ("x", "lines"):
        if key in rep and not isinstance(rep[key], str):  # a list or table is not hashable, nor an axis
            r.fail(f"report.{key}", f"expected the name of a sweep axis, got {rep[key]!r}")
        if key in rep and rep[key] not in sweep:
            r.fail(f"report.{key}", f"{rep[key]!r} is not a sweep axis{suggest(str(rep[key]), sweep)}")
    base = _base(st, emulators, r, path.parent)
    study = Study(name=str(st.get("name", path.stem)), base=base, axes=dict(sweep), report=dict(rep),
                  source=r.source, text=path.read_text(), description=str(st.get("description", "")))
    _check_runs(study, r)
    return _with_variations(study, raw, r)


def _with_variations(study: Study, raw: dict, r: TomlReader) -> Study:
    """The study with its headline run and its checked ``[sensitivity]`` and ``[tradeoff]`` tables."""
    headline = around.check_headline(study.report, study.runs(), r)
    repeats = study.base["repeats"]
    sensitivity = r.table(raw, "sensitivity")
    if sensitivity:
        preset = load_preset(headline.get("sensor", study.base["sensor"]))
        sensitivity = around.check_sensitivity(sensitivity, preset, r, repeats)

    def check_setting(setting: dict) -> None:
        reader = TomlReader("")
        _check_sweep({k: [v] for k, v in setting.items()}, reader)
        try:
            emulator_params({**headline, **setting})
        except FieldError as err:
            reader.fail(err.field, str(err))

    tradeoff = around.check_tradeoff(r.table(raw, "tradeoff"), r, repeats, check_setting)
    return dataclasses.replace(study, headline=headline, sensitivity=sensitivity, tradeoff=tradeoff)


def _check_study_table(st: dict, r: TomlReader) -> tuple[str, ...]:
    """``[study]``'s keys, scene and flicker group; returns its emulators."""
    check_keys(st, STUDY_KEYS, source=r.source, where="study")
    if not isinstance(st.get("scene"), str):
        r.fail("study.scene", "missing: a scene name or manifest path" if "scene" not in st else
               f"expected a scene name or manifest path, got {st['scene']!r}")
    group = st.get("flicker_group")
    if not (isinstance(group, str) or (isinstance(group, dict) and group
                                       and all(isinstance(v, str) for v in group.values()))):
        r.fail("study.flicker_group", "missing: the light group whose waveform the sweep changes "
                                      "(a name, or a table scene = group)")
    try:
        return check_emulator_list(st.get("emulators", list(EMULATORS)))
    except ValueError as exc:
        r.fail("study.emulators", str(exc))


def _check_sweep(sweep: dict, r: TomlReader) -> None:
    """Each sweep axis a non-empty list of values of its type and range."""
    check_keys(sweep, AXES, source=r.source, where="sweep")
    for axis, values in sweep.items():
        if not isinstance(values, list) or not values:
            r.fail(f"sweep.{axis}", f"expected a non-empty list, got {values!r}")
    for w in sweep.get("waveform", []):
        if w not in WAVEFORMS:
            r.fail("sweep.waveform", f"unknown waveform {w!r}{suggest(str(w), WAVEFORMS)}")
    for axis in ("frequency_hz", "duty", "modulation", "light_scale", "flicker_scale") + SENSOR_AXES:
        low = 0.0 if axis in SENSOR_AXES else None  # sensor parameters may be 0 (off)
        for v in sweep.get(axis, []):
            bad = isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
            if bad or (v < low if low is not None else v <= 0):
                r.fail(f"sweep.{axis}", f"expected {'non-negative' if low is not None else 'positive'} numbers, "
                                        f"got {v!r}")
    for axis in ("duty", "modulation"):  # fractions of the period and of the mean: refused here, not after the render
        for v in sweep.get(axis, []):
            if v > 1:
                r.fail(f"sweep.{axis}", f"expected fractions in (0, 1], got {v!r}")
    for axis, cap in (("frequency_hz", MAX_FREQUENCY_HZ), ("light_scale", MAX_LIGHT_SCALE),
                      ("flicker_scale", MAX_LIGHT_SCALE)):  # the caps of a waveform and of emulation's light scale
        for v in sweep.get(axis, []):
            if v > cap:
                r.fail(f"sweep.{axis}", f"{v!r} is above {cap:g}")
    for values in sweep.get("thresholds_ln", []):
        if (not isinstance(values, list) or not values
                or not all(isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t) and t > 0
                           for t in values)):
            r.fail("sweep.thresholds_ln", f"expected lists of positive finite numbers (one threshold set each), "
                                          f"got {values!r}")
    for v in sweep.get("window", []):  # [width, height]: the rendered (with footprint = "chip": the chip's) window
        if not (isinstance(v, list) and len(v) == 2 and all(isinstance(n, int) and not isinstance(n, bool)
                                                              and 0 < n <= 100_000 for n in v)):
            r.fail("sweep.window", f"expected [width, height] pairs of positive pixel counts, got {v!r}")
    for v in sweep.get("hysteresis_ln", []):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            r.fail("sweep.hysteresis_ln", f"expected non-negative numbers, got {v!r}")
    for axis, what in (("sensor", "sensor preset names or .toml paths"), ("scene", "scene names or .toml paths")):
        for v in sweep.get(axis, []):
            if not isinstance(v, str):
                r.fail(f"sweep.{axis}", f"expected {what}, got {v!r}")


def _base(st: dict, emulators: tuple[str, ...], r: TomlReader, folder: Path) -> dict:
    """The settings every run shares: ``[study]``'s time grid, seed, methods, render and repeats."""
    grid = TimeGrid.from_section(st, source=r.source, where="study", base=STUDY_TIME)
    if not grid.frame_rate_hz > 0:  # reconstructions are scored at the ground-truth frames
        r.fail("study.frame_rate_hz", f"must be > 0 (frames score the reconstructions), got {grid.frame_rate_hz}")
    base = {"scene": st["scene"], "sensor": resolve_relative(st.get("sensor", "davis346"), folder),
            "emulators": list(emulators),
            "flicker_group": st["flicker_group"], "seed": r.number(st, "seed", "study", 0, minimum=0, integer=True),
            **dataclasses.asdict(grid),
            "methods": list(st.get("methods", ["dct", "direct"])), "render": dict(st.get("render", {})),
            "repeats": r.number(st, "repeats", "study", DEFAULT_REPEATS, positive=True, integer=True,
                                maximum=MAX_REPEATS)}
    try:  # the time grid's own checks (whole steps, at least one clock tick), before any work
        TimeGrid(**{k: base[k] for k in ("duration_s", "step_s", "chunk_steps", "frame_rate_hz")}).steps(
            base["duration_s"])
    except FieldError as err:
        r.fail(f"study.{err.field}", str(err))
    if not isinstance(base["sensor"], str):
        r.fail("study.sensor", f"expected a sensor preset name or .toml path, got {base['sensor']!r}")
    if "footprint" in st:  # only when given: the runs of studies without it keep their ids
        base["footprint"] = check_footprint(st, r, "study")
    return base


def _message(exc: ConfigError) -> str:
    """An error's message without the key it names (the caller names its own)."""
    text = str(exc)
    return text[len(exc.key) + 2:] if exc.key and exc.source is None and text.startswith(f"{exc.key}: ") else text


def _check_runs(study: Study, r: TomlReader) -> None:
    """Every sweep value, and every run's combination of them, as the runs will use them: before the first
    run starts, errors name the study file, the sweep key and the value (or run)."""
    from gevsim.pixel.presets import with_overrides

    sweep = study.axes
    sensors = sweep.get("sensor", [study.base["sensor"]])
    presets = {}
    for i, name in enumerate(sensors):
        try:
            presets[name] = load_preset(name)
        except ConfigError as exc:
            key = "sweep.sensor" if "sensor" in sweep else "study.sensor"
            r.fail(key, f"value {i + 1} of {len(sensors)}: {_message(exc)}" if "sensor" in sweep else _message(exc))
    for axis in (a for a in SENSOR_AXES if a in sweep):
        for i, value in enumerate(sweep[axis]):
            for preset in presets.values():
                try:
                    with_overrides(preset, {axis: value})
                except ConfigError as exc:
                    r.fail(f"sweep.{axis}", f"value {i + 1} of {len(sweep[axis])}: {_message(exc)}")
    at_most(math.prod(len(v) for v in sweep.values()), MAX_STUDY_RUNS, source=study.source, key="sweep",
            what="the number of runs (the product of the sweep axes' lengths)")
    runs = study.runs()
    for k, params in enumerate(runs):
        where = f"run {k + 1} of {len(runs)}: {json.dumps(params)}"
        try:
            emulator_params(params)
        except FieldError as err:
            r.fail(f"sweep.{err.field}", f"{err} ({where})")
        overrides = {a: params[a] for a in SENSOR_AXES if a in params}
        if len(overrides) > 1:
            try:
                with_overrides(presets[params.get("sensor", study.base["sensor"])], overrides)
            except ConfigError as exc:
                r.fail("sweep", f"{_message(exc)} ({where})")


def flicker_group(study: Study, scene: str) -> str:
    """The swept light group of a scene (``flicker_group`` is a name or a table scene = group)."""
    group = study.base["flicker_group"]
    if isinstance(group, str):
        return group
    if scene not in group:
        raise ConfigError(f"no flicker group given for scene {scene!r}", source=study.source, key="study.flicker_group")
    return group[scene]


def waveform_spec(params: dict) -> dict | None:
    """The flickering group's waveform table for a run's parameters (None: the scene's own); the lamp type
    makes it from the swept light frequency (:meth:`gevsim.illumination.base.Waveform.swept`)."""
    kind = params.get("waveform", NATIVE)
    if kind == NATIVE:
        return None
    return swept_spec(kind, float(params.get("frequency_hz", 100.0)), params)


def emulator_params(params: dict) -> dict:
    """The emulators' parameters of a run (:data:`~gevsim.emulation.emulators.PARAMS`; swept ones from
    ``params``, the others their defaults), as :class:`~gevsim.emulation.EmulationConfig` fields; a bad
    combination raises :class:`~gevsim._validate.FieldError`."""
    out: dict = {}
    for cls in PARAMS:
        out.update(dataclasses.asdict(cls(**{f.name: params[f.name] for f in dataclasses.fields(cls)
                                             if f.name in params})))
    return out


def run_scene(study: Study, params: dict) -> str:
    """The scene of a run: a built-in name, or a manifest path (relative ones resolved from the study file)."""
    return resolve_relative(params.get("scene", study.base["scene"]), Path(study.source).parent)


def run_emulators(study: Study, params: dict) -> list[str]:
    """The emulators of a run: the study's, but for a sensitivity run (its parameters hold ``assumed``) only the
    pair its answer compares (:data:`~gevsim.emulation.emulators.HEADLINE`)."""
    if around.is_sensitivity(params):
        return [e for e in study.base["emulators"] if e in HEADLINE]
    return list(study.base["emulators"])


def run_render(study: Study, params: dict) -> dict:
    """The render overrides of a run: the study's, with a swept ``window``'s width and height."""
    render = dict(study.base["render"])
    if "window" in params:
        render.update(width=int(params["window"][0]), height=int(params["window"][1]))
    return render


def run_config(study: Study, params: dict, *, seed: int | None = None) -> EmulationConfig:
    """The emulation config of a run (with noise seed ``seed``; default: the study's)."""
    b = study.base
    group = flicker_group(study, params.get("scene", b["scene"]))
    scene = run_scene(study, params)
    wave = waveform_spec(params)
    cfg = EmulationConfig(
        scene=scene, sensor=params.get("sensor", b["sensor"]), emulators=tuple(run_emulators(study, params)),
        seed=b["seed"] if seed is None else seed,
        duration_s=b["duration_s"], step_s=b["step_s"], chunk_steps=b["chunk_steps"],
        frame_rate_hz=b["frame_rate_hz"], render=run_render(study, params), footprint=b.get("footprint", "scene"),
        aps=(any(METHODS[m].needs_aps for m in b["methods"])
             and load_preset(params.get("sensor", b["sensor"])).aps is not None),
        aps_exposure_s=min(5e-4, 0.5 / b["frame_rate_hz"]),
        **emulator_params(params),
        sensor_overrides={**{k: params[k] for k in SENSOR_AXES if k in params}, **params.get("assumed", {})},
        light_scale=float(params.get("light_scale", 1.0)),
        group_scale={group: float(params.get("flicker_scale", 1.0))},
        group_waveform={group: wave} if wave else {}, source=study.source)
    return dataclasses.replace(cfg, text=cfg.to_toml())


def run_id(study: Study, params: dict) -> str:
    """Identity of a run: its base settings and parameters (not the number of repeats, so a study given
    more repeats keeps the finished ones; not chunk_steps, which no result depends on), the contents of
    every file its scene is made of (manifest, builder, textures: :func:`gevsim.render.inputs.scene_digest`),
    of its sensor preset (:func:`gevsim.pixel.presets.preset_digest`) and of the learned methods' weights, and
    the gevsim version. A rerun after any of them changed computes the run again."""
    from gevsim.learn.shipped import weights_digest
    from gevsim.pixel.presets import preset_digest
    from gevsim.render.inputs import scene_digest

    base = {k: v for k, v in study.base.items() if k not in ("repeats", "chunk_steps")}
    sensor = params.get("sensor", study.base["sensor"])
    payload = json.dumps({"base": base, "params": params, "scene_sha256": scene_digest(run_scene(study, params)),
                          "sensor_sha256": preset_digest(sensor), "gevsim": __version__,
                          **weights_digest(study.base.get("methods"))}, sort_keys=True, default=str)
    return hashlib.sha256(payload.encode()).hexdigest()[:16]
