"""The emulation config: which scene, sensor, emulators, time grid and outputs.

Every key, its unit, default and range: docs/config.md (the reference of every config file).

```toml
[emulation]
scene = "office"               # built-in scene or manifest path (relative to this file)
sensor = "davis346"            # sensor preset name or TOML path
emulators = ["dvs", "gradient", "gradient_rc", "csdvs"]
seed = 1
duration_s = 0.02              # default: the scene's
step_s = 2e-5                  # pixel-model time step
chunk_steps = 256              # steps per chunk (bounds memory, not results); default: from the memory budget
frame_rate_hz = 1000.0         # ground-truth frames (0: none)
aps = false                    # also emulate APS frames (needs the preset's [aps])
aps_exposure_s = 5e-4
cold_start = false             # true: the sensor starts as if just switched on (no leak before 1 / rate)
burn_in_s = 0.01               # the chain runs this long (whole lamp periods) before t = 0, events discarded
footprint = "scene"            # "chip": the pixels are a centred window of the chip at its native pitch
crossings = "samples"          # "bridge": the DVS finds crossings inside steps up to 2 ms (dvs only)

[render]                       # overrides of the scene manifest's [render]
width = 64
height = 48
spp = 4

[gradient]
thresholds_ln = [0.05, 0.1, 0.2]   # assigned by (x + y) mod n
hysteresis_ln = 0.0                # comparator hysteresis (0: the paper's definition)

[csdvs]
surround_length_px = 2.0
surround_tau_s = 1e-3

[sensor]                       # overrides of the preset's parameters, by name
threshold_mismatch_ln = 0.03

[light]                        # changes that need no re-rendering (light transport is linear)
scale = 1.0                    # every light group's radiance times this (light level)
[light.groups.ceiling]         # per light group of the scene
scale = 1.0
waveform = { type = "pwm", frequency_hz = 300.0, duty = 0.5 }
```
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, TypeVar

from gevsim._validate import FieldError
from gevsim.config import FromTable, TomlReader, load_table, resolve_relative
from gevsim.emulation.bridging import CROSSING_RULES
from gevsim.emulation.emulators import EMULATORS, PARAMS, GradientConfig, SurroundConfig, check_emulator_list
from gevsim.errors import ConfigError, check_keys
from gevsim.render.manifest_checks import MAX_LUMINANCE_CD_M2
from gevsim.render.quality import check_render_overrides
from gevsim.timebase import TimeGrid

#: The emulators' own tables (:data:`gevsim.emulation.emulators.PARAMS`) sit between [render] and [light].
TABLES = ("emulation", "render", *(cls.TABLE for cls in PARAMS), "light", "sensor")
#: The largest factor on a light group's radiance (light.scale times its group's scale): one that takes a dim
#: 1 cd/m^2 emitter to the brightest a manifest may state (1e10 cd/m^2). light.scale = 1e300 gave an infinite
#: photocurrent after the render.
MAX_LIGHT_SCALE = MAX_LUMINANCE_CD_M2 / 1.0
EMULATION_KEYS = ("scene", "sensor", "emulators", "seed", "duration_s", "step_s", "chunk_steps", "frame_rate_hz",
                  "aps", "aps_exposure_s", "cold_start", "burn_in_s", "footprint", "crossings")
#: How long the pixel chain runs before t = 0 by default, rounded up to whole lamp periods (issue 34: with
#: the DVS levels drawn from their stationary law, 10 ms settles the rest; docs/start-state.md measures it).
BURN_IN_S = 0.01
#: ``scene``: the emulated pixels span the scene's field of view; ``chip``: a centred window of the chip at its
#: native pitch (:mod:`gevsim.emulation.footprint`).
FOOTPRINTS = ("scene", "chip")
#: The longest burn-in a config may ask for.
MAX_BURN_IN_S = 10.0

P = TypeVar("P", bound=FromTable)


@dataclass(frozen=True)
class EmulationConfig:
    """An emulation: what :func:`gevsim.emulation.driver.run` needs (a config file's contents, or built here).

    The time grid's fields and the emulators' parameters are flat keyword fields, as the config's
    Python users write them (``EmulationConfig(scene="office", thresholds_ln=(0.1, 0.2))``,
    ``dataclasses.replace(config, hysteresis_ln=0.02)``), typed and visible to mypy. Their defaults are
    the dataclasses' own (:class:`~gevsim.timebase.TimeGrid`, and the ``params`` dataclass of each entry
    of :data:`~gevsim.emulation.emulators.EMULATORS`), and so are their checks: :attr:`time` and
    :meth:`params` build the dataclass from these fields. A mapping of parameter objects instead would
    need a hand-written ``__init__`` to keep that keyword API; the cost of flat fields is one line per
    parameter here for an emulator with parameters, and importing this module fails where one is missing
    or its default differs (:func:`_check_emulator_fields`).
    """

    scene: str
    sensor: str = "davis346"
    emulators: tuple[str, ...] = tuple(EMULATORS)
    seed: int = 0
    duration_s: float | None = TimeGrid.duration_s
    step_s: float = TimeGrid.step_s
    chunk_steps: int | None = TimeGrid.chunk_steps  # None: sized to the memory budget (resources.budget_chunk_steps)
    frame_rate_hz: float = TimeGrid.frame_rate_hz
    aps: bool = False
    aps_exposure_s: float = 5e-4
    cold_start: bool = False  # True: every pixel starts as if just switched on (leak phase 0)
    burn_in_s: float = BURN_IN_S  # the chain runs this long before t = 0 (not with cold_start)
    footprint: str = "scene"  # "chip": a centred window of the chip at native pitch (gevsim.emulation.footprint)
    crossings: str = "samples"  # "bridge": crossings between long steps (gevsim.emulation.bridging)
    render: dict = field(default_factory=dict)
    thresholds_ln: tuple[float, ...] = GradientConfig.thresholds_ln
    hysteresis_ln: float = GradientConfig.hysteresis_ln
    surround_length_px: float = SurroundConfig.surround_length_px
    surround_tau_s: float = SurroundConfig.surround_tau_s
    sensor_overrides: dict = field(default_factory=dict)  # preset parameter -> value
    light_scale: float = 1.0
    group_scale: dict = field(default_factory=dict)  # light group -> radiance factor
    group_waveform: dict = field(default_factory=dict)  # light group -> waveform spec table
    source: str = ""
    text: str = ""

    @property
    def time(self) -> TimeGrid:
        """The time grid (validated: a bad value raises :class:`~gevsim._validate.FieldError`)."""
        return TimeGrid(**{f.name: getattr(self, f.name) for f in fields(TimeGrid)})

    def params(self, cls: type[P]) -> P:
        """An emulator's parameters (``cls`` one of :data:`~gevsim.emulation.emulators.PARAMS`) from the
        fields of the same names (validated: a bad value raises :class:`~gevsim._validate.FieldError`)."""
        return cls(**{f.name: getattr(self, f.name) for f in fields(cls)})

    def to_toml(self) -> str:
        """The config as TOML (what an emulation file records; programmatic configs too)."""
        import tomli_w

        em = {k: getattr(self, k) for k in ("scene", "sensor", "seed", "step_s", "chunk_steps", "frame_rate_hz", "aps",
                                             "aps_exposure_s", "cold_start", "burn_in_s", "footprint", "crossings")}
        if self.chunk_steps is None:  # from the memory budget: TOML has no None
            del em["chunk_steps"]
        em["emulators"] = list(self.emulators)
        if self.duration_s is not None:
            em["duration_s"] = self.duration_s
        groups = {g: {"scale": self.group_scale.get(g, 1.0), **({"waveform": self.group_waveform[g]}
                                                                 if g in self.group_waveform else {})}
                  for g in sorted(set(self.group_scale) | set(self.group_waveform))}  # not set order (#18)
        emulator_tables = {cls.TABLE: {f.name: _toml_value(getattr(self, f.name)) for f in fields(cls)}
                           for cls in PARAMS}
        return tomli_w.dumps({
            "emulation": em, "render": dict(self.render), **emulator_tables,
            "light": {"scale": self.light_scale, "groups": groups},
            "sensor": dict(self.sensor_overrides),
        })


def _toml_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def _check_emulator_fields() -> None:
    """Every parameter of every emulator is a field of :class:`EmulationConfig` with the dataclass's default."""
    ours = {f.name: f.default for f in fields(EmulationConfig)}
    for cls in PARAMS:
        for f in fields(cls):
            if f.name not in ours or ours[f.name] != f.default:
                raise TypeError(f"EmulationConfig needs the field {f.name} = {cls.__name__}.{f.name} "
                                f"([{cls.TABLE}] parameter)")


_check_emulator_fields()


def load_config(path: str | Path) -> EmulationConfig:
    """Read and validate an emulation config; errors name the file and key."""
    path = Path(path)
    raw, r = load_table(path, what="emulation config", tables=TABLES)
    em = r.table(raw, "emulation")
    check_keys(em, EMULATION_KEYS, source=r.source, where="emulation")
    scene, sensor = _scene_and_sensor(em, r, path.parent)
    try:
        emulators = check_emulator_list(em.get("emulators", list(EMULATORS)))
    except ValueError as exc:
        r.fail("emulation.emulators", str(exc))
    render = r.table(raw, "render")
    check_render_overrides(render, r, "render")
    emulator_params: dict[str, Any] = {}
    for cls in PARAMS:  # each emulator's table, checked by its dataclass
        emulator_params.update(asdict(cls.from_table(raw.get(cls.TABLE, {}), source=r.source)))
    light_scale, group_scale, group_waveform = _light(raw, r)
    flags: dict[str, Any] = {}
    for key in ("aps", "cold_start"):
        flags[key] = em.get(key, False)
        if not isinstance(flags[key], bool):
            r.fail(f"emulation.{key}", f"expected true or false, got {flags[key]!r}")
    grid = TimeGrid.from_section(em, source=r.source, where="emulation")
    _check_light_product(light_scale, group_scale, r)
    return EmulationConfig(
        scene=scene,
        sensor=sensor,
        emulators=tuple(emulators),
        seed=r.number(em, "seed", "emulation", 0, minimum=0, integer=True),
        **asdict(grid),
        **flags,
        aps_exposure_s=float(r.number(em, "aps_exposure_s", "emulation", 5e-4, positive=True)),
        burn_in_s=float(r.number(em, "burn_in_s", "emulation", BURN_IN_S, minimum=0.0, maximum=MAX_BURN_IN_S)),
        footprint=check_footprint(em, r, "emulation"),
        crossings=_crossings(em, r),
        render=dict(render),
        **emulator_params,
        sensor_overrides=dict(r.table(raw, "sensor")),
        light_scale=light_scale,
        group_scale=group_scale,
        group_waveform=group_waveform,
        source=r.source,
        text=path.read_text(),
    )


def _crossings(em: dict, r: TomlReader) -> str:
    """emulation.crossings: a name of :data:`gevsim.emulation.bridging.CROSSING_RULES`."""
    value = em.get("crossings", "samples")
    if value not in CROSSING_RULES:
        r.fail("emulation.crossings", f"expected one of {', '.join(map(repr, CROSSING_RULES))}, got {value!r}")
    return str(value)


def check_footprint(table: dict, r: TomlReader, where: str) -> str:
    """``<where>.footprint`` (emulation or study config): one of :data:`FOOTPRINTS`, "scene" when absent."""
    value = table.get("footprint", "scene")
    if value not in FOOTPRINTS:
        r.fail(f"{where}.footprint", f"expected one of {', '.join(repr(f) for f in FOOTPRINTS)}, got {value!r}")
    return str(value)


def _scene_and_sensor(em: dict, r: TomlReader, folder: Path) -> tuple[str, str]:
    """``emulation.scene`` and ``emulation.sensor``: names, or ``.toml`` paths taken from the config's folder."""
    if not isinstance(em.get("scene"), str):
        r.fail("emulation.scene", "missing: a built-in scene name or a manifest path" if "scene" not in em else
               f"expected a built-in scene name or a manifest path, got {em['scene']!r}")
    scene = resolve_relative(em["scene"], folder)
    sensor = em.get("sensor", "davis346")
    if not isinstance(sensor, str):
        r.fail("emulation.sensor", f"expected a preset name or path, got {sensor!r}")
    sensor = resolve_relative(sensor, folder)
    _check_names(scene, sensor, r)
    return scene, sensor


def _light(raw: dict, r: TomlReader) -> tuple[float, dict[str, float], dict[str, dict]]:
    """``[light]``: its scale, and each light group's scale and waveform table (validated now)."""
    light = r.table(raw, "light")
    check_keys(light, ("scale", "groups"), source=r.source, where="light")
    groups = r.table(light, "groups", "light.")
    group_scale, group_waveform = {}, {}
    for name, spec in groups.items():
        where = f"light.groups.{name}"
        if not isinstance(spec, dict):
            r.fail(where, f"expected a table, got {spec!r}")
        check_keys(spec, ("scale", "waveform"), source=r.source, where=where)
        if "scale" in spec:
            group_scale[name] = float(r.number(spec, "scale", where, minimum=0.0))
        if "waveform" in spec:
            from gevsim.illumination import from_spec

            from_spec(spec["waveform"], source=r.source, key=f"{where}.waveform")  # validate now
            group_waveform[name] = dict(spec["waveform"])
    light_scale = float(r.number(light, "scale", "light", 1.0, positive=True, maximum=MAX_LIGHT_SCALE))
    return light_scale, group_scale, group_waveform


def _check_light_product(light_scale: float, group_scale: dict[str, float], r: TomlReader) -> None:
    for name, scale in group_scale.items():
        if scale * light_scale > MAX_LIGHT_SCALE:
            r.fail(f"light.groups.{name}.scale", f"{scale:g} (times light.scale = {light_scale:g}) is above "
                   f"{MAX_LIGHT_SCALE:g}, the factor that takes a 1 cd/m^2 emitter to the brightest gevsim renders")


def _check_names(scene: str, sensor: str, r: TomlReader) -> None:
    """An unknown built-in scene or sensor preset name is refused now, naming this file and key (#19)."""
    from gevsim.pixel.presets import preset_path
    from gevsim.render.manifest import resolve

    for key, check, value in (("emulation.scene", resolve, scene), ("emulation.sensor", preset_path, sensor)):
        try:
            check(value)
        except ConfigError as exc:
            r.fail(key, str(exc))


def check_consistency(config: EmulationConfig, *, duration_s: float) -> None:
    """Cross-field checks once the scene's duration is known."""
    try:
        config.time.steps(duration_s)
    except FieldError as err:
        raise ConfigError(str(err), source=config.source, key=f"emulation.{err.field}") from None
    for cls in PARAMS:  # each emulator's parameters, checked by its dataclass
        try:
            config.params(cls)
        except FieldError as err:
            raise ConfigError(str(err), source=config.source, key=f"{cls.TABLE}.{err.field}") from None
    if config.aps and config.frame_rate_hz <= 0:
        raise ConfigError("aps = true needs frame_rate_hz > 0", source=config.source, key="emulation.aps")
    if config.crossings != "samples":
        others = [n for n in config.emulators if not EMULATORS[n].bridges]
        if others or config.cold_start:
            why = (f"the {', '.join(others)} emulator(s) take no bridge" if others
                   else "it starts from a settled photoreceptor (cold_start = false)")
            raise ConfigError(f"crossings = {config.crossings!r} is for the dvs and gradient emulators only so far: "
                              f"{why}", source=config.source, key="emulation.crossings")
        if "gradient" in config.emulators and config.hysteresis_ln > 0.0:
            raise ConfigError(f"crossings = {config.crossings!r} needs hysteresis_ln = 0 for the gradient emulator "
                              f"(got {config.hysteresis_ln!r})", source=config.source, key="emulation.crossings")
    if config.aps and config.aps_exposure_s > 1.0 / max(config.frame_rate_hz, 1e-12):
        raise ConfigError("aps_exposure_s exceeds the frame period", source=config.source,
                          key="emulation.aps_exposure_s")
