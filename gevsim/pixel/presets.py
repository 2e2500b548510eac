"""Sensor presets: TOML files under ``noise/`` with their sources in comments.

A preset has the tables ``[sensor]`` (geometry), ``[photoreceptor]``,
``[noise]``, ``[events]`` and optionally ``[aps]``, ``[readout]`` and ``[stated]`` (what the whole
pixel does, as a bench measures it: :class:`StatedBehaviour`). The photoreceptor cutoff
may be stated at an illuminance (``cutoff_ref_lux``, as datasheets do); it is
converted to photocurrent with the pixel area, fill factor and the silicon
responsivity for ``bandwidth_reference_spectrum``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gevsim._validate import real
from gevsim.config import FieldError, FromTable, load_table, resource_tomls
from gevsim.errors import ConfigError, check_keys, suggest
from gevsim.pixel.aps import ApsParams
from gevsim.pixel.assumed import ASSUMED_TABLES, SENSOR_FIELDS, Assumed, parse_assumed
from gevsim.pixel.params import EventParams, NoiseParams, PhotoreceptorParams, ReadoutParams

TABLES = ("sensor", "photoreceptor", "noise", "events", "aps", "readout", "stated", "assumed")
SENSOR_KEYS = ("name", "description", "width", "height", "pixel_pitch_m", "fill_factor",
               "bandwidth_reference_spectrum", "quantum_efficiency")
#: The least dark current of a preset's median pixel, in electrons per second (1.6e-19 A). Far below it,
#: black pixels' photoreceptors have cutoffs of picohertz and their noise no finite settled value (davis346 at
#: dark_current_a = 1e-26 A gave NaN after the render).
MIN_DARK_ELECTRONS_PER_S = 1.0
#: The brightest reference illuminance: pi x 1e10 lux, as bright as a scene manifest's light may be
#: (gevsim.render.manifest_checks.MAX_LIMITS); 1e300 lux gave an infinite signal after the render.
MAX_CUTOFF_REF_LUX = 3.1415926535897932e10


@dataclass(frozen=True)
class StatedBehaviour(FromTable):
    """What a preset says its whole pixel does, as a bench would measure it (a preset's ``[stated]``
    table, issue 34): the behaviour of the chain, not of one of its parameters. ``gevsim validate``
    measures each statement at its own conditions and fails a row when they differ by more than 10 %.

    Parameters
    ----------
    bandwidth_hz : the -3 dB frequency of the whole chain (photoreceptor and every pole after it) for a
        small sinusoidal modulation of the light, at ``bandwidth_chip_lux`` (None: not stated).
    bandwidth_chip_lux : the chip (focal-plane) illuminance, D65, at which ``bandwidth_hz`` holds.
    latency_s : the delay from a step of ``latency_step_ln`` (ln photocurrent, upward) to the first ON
        event, noise-free, at the nominal threshold, the readout's fixed latency included, at
        ``latency_chip_lux`` (None: not stated).
    latency_step_ln : the step's contrast in ln units (1.0: the light rises by e = 2.72x; ln 1.3 = 0.262: 30 %).
    latency_chip_lux : the chip illuminance, D65, before the step.
    """

    TABLE = "stated"

    bandwidth_hz: float | None = None
    bandwidth_chip_lux: float = 1000.0
    latency_s: float | None = None
    latency_step_ln: float = 1.0
    latency_chip_lux: float = 1000.0

    def __post_init__(self):
        for name in ("bandwidth_hz", "latency_s"):
            if getattr(self, name) is not None:
                real(getattr(self, name), name, low=0, low_open=True)
        for name in ("bandwidth_chip_lux", "latency_chip_lux"):
            real(getattr(self, name), name, low=0, low_open=True, high=MAX_CUTOFF_REF_LUX)
        real(self.latency_step_ln, "latency_step_ln", low=0, low_open=True, high=20.0)
        if self.latency_s is not None and self.latency_s > 1.0:
            raise FieldError("latency_s", f"latency_s must be at most 1 s, got {self.latency_s!r}")


@dataclass(frozen=True)
class SensorPreset:
    """A named sensor: geometry plus photoreceptor, noise, event and (optional) APS parameters."""

    name: str
    description: str
    width: int
    height: int
    pixel_pitch_m: float
    fill_factor: float
    photoreceptor: PhotoreceptorParams
    noise: NoiseParams
    events: EventParams
    aps: ApsParams | None
    source: str
    readout: ReadoutParams = ReadoutParams()  # no limit unless the preset's [readout] says
    quantum_efficiency: str = "fsi"  # a name in gevsim.optics.QE_CURVES
    stated: StatedBehaviour = StatedBehaviour()  # nothing stated unless the preset's [stated] says
    bandwidth_reference_spectrum: str = "D65"  # the light cutoff_ref_lux is stated for
    cutoff_ref_lux: float | None = None  # the chip lux at which cutoff_hz holds, as the file states it (None: in A)
    #: The plausible range of each assumed number, by "table.field" (the preset's [assumed.*] tables;
    #: gevsim.pixel.assumed). Metadata: not compared, so presets hash as before.
    assumed: dict[str, Assumed] = field(default_factory=dict, compare=False)

    @property
    def qe(self) -> tuple:
        """The (wavelengths_nm, qe) table of the sensor's silicon."""
        from gevsim.optics import QE_CURVES

        return QE_CURVES[self.quantum_efficiency]

    def ideal(self) -> SensorPreset:
        """The same sensor with every noise mechanism off (counterfactual runs): each entry of
        :data:`gevsim.pixel.mechanisms.NOISE_MECHANISMS` at its off state, but for the keys an entry's
        ``ideal_keeps`` keeps with its reason (the comparator offsets, as before the
        registry). The mean dark current stays (the floor of the log response, not a noise); its spread
        (DSNU) goes."""
        import dataclasses

        from gevsim.pixel.mechanisms import ideal_values

        return dataclasses.replace(
            self,
            name=f"{self.name}-noise-free",
            noise=dataclasses.replace(self.noise, **ideal_values("noise")),
            events=dataclasses.replace(self.events, **ideal_values("events")),
        )


#: The tables a qualified override (``"noise.dc_offset_v"``) may name; an unqualified name goes to the first of
#: ``OWNERS`` with that field (or to the sensor's ``pixel_pitch_m``, ``fill_factor``).
QUALIFIED_TABLES = ASSUMED_TABLES
OWNERS = ("photoreceptor", "noise", "events", "readout")


def with_overrides(preset: SensorPreset, overrides: dict, *, source: str | None = None,
                   where: str = "") -> SensorPreset:
    """A copy with parameters replaced by name, wherever they live: the sensor geometry
    (``pixel_pitch_m``, ``fill_factor``) or a field of ``photoreceptor``, ``noise``,
    ``events``, ``readout`` (e.g. ``cutoff_hz``, ``dark_current_a``, ``threshold_mismatch_ln``), the first
    of them with that field; or by qualified name ``table.field`` (``"noise.prnu"``, ``"aps.prnu"``,
    ``"sensor.quantum_efficiency"``), as :attr:`SensorPreset.assumed` names them.

    ``photoreceptor.cutoff_ref_lux`` and ``sensor.bandwidth_reference_spectrum`` convert the cutoff's reference
    again, as loading the file would (with the preset's own geometry and QE); a changed pitch, fill factor or
    QE keeps the reference photocurrent (a property of the circuit).
    Errors name ``source`` and the key, inside the table ``where`` (``sensor`` in an emulation config)."""
    import dataclasses

    prefix = f"{where}." if where else ""
    parts: dict[str, Any] = {"photoreceptor": preset.photoreceptor, "noise": preset.noise, "events": preset.events,
                             "readout": preset.readout, "aps": preset.aps}
    top: dict[str, Any] = {}
    touched: set[str] = set()
    for key, value in overrides.items():
        table, name = _owner(key, parts, source=source, key_name=prefix + key)
        touched.add(name)
        if table == "sensor" or name == "cutoff_ref_lux":
            top[name] = _sensor_value(name, value, source=source, key=prefix + key)
            continue
        try:
            parts[table] = dataclasses.replace(parts[table], **{name: value})
        except ValueError as exc:
            raise ConfigError(str(exc), source=source, key=prefix + key) from None
    if {"cutoff_ref_lux", "bandwidth_reference_spectrum"} & set(top):
        key = next(k for k in overrides if k.endswith(("cutoff_ref_lux", "bandwidth_reference_spectrum")))
        if "cutoff_ref_photocurrent_a" in touched:
            raise ConfigError("give cutoff_ref_lux or cutoff_ref_photocurrent_a, not both", source=source,
                              key=prefix + key)
        lux = top.get("cutoff_ref_lux", preset.cutoff_ref_lux)
        if lux is not None:
            from gevsim.optics import QE_CURVES

            current = lux_to_photocurrent_a(
                lux, pixel_pitch_m=preset.pixel_pitch_m, fill_factor=preset.fill_factor,
                spectrum=top.get("bandwidth_reference_spectrum", preset.bandwidth_reference_spectrum),
                source=source, qe=QE_CURVES[preset.quantum_efficiency])
            parts["photoreceptor"] = dataclasses.replace(parts["photoreceptor"], cutoff_ref_photocurrent_a=current)
    changed = next((k for k in overrides if k.rpartition(".")[2] in
                    ("dark_current_a", "dark_current_spread", "temperature_k", "dark_current_doubling_k")), None)
    if changed is not None:  # the keys the dark-current floor depends on
        check_dark_current(parts["photoreceptor"], parts["noise"], source=source, key=prefix + changed)
    return dataclasses.replace(preset, **parts, **top)


def parameter_value(preset: SensorPreset, key: str) -> Any:
    """The value of a parameter named as :func:`with_overrides` names it (``"noise.dc_offset_v"``,
    ``"sensor.fill_factor"``, ``"photoreceptor.cutoff_ref_lux"``, or an unqualified field): what an
    :class:`~gevsim.pixel.assumed.Assumed` ``value`` is compared with."""
    parts = {"photoreceptor": preset.photoreceptor, "noise": preset.noise, "events": preset.events,
             "readout": preset.readout, "aps": preset.aps}
    table, name = _owner(key, parts, source=preset.source, key_name=key)
    if table == "sensor" or name == "cutoff_ref_lux":
        return getattr(preset, name)
    return getattr(parts[table], name)


def _owner(key: str, parts: dict[str, Any], *, source: str | None, key_name: str) -> tuple[str, str]:
    """(table, field) of an override's key: ``table.field``, or a bare field of the sensor or of the first of
    ``OWNERS`` that has it."""
    import dataclasses

    def fields(table: str) -> list[str]:
        obj = parts[table]
        return [] if obj is None else [f.name for f in dataclasses.fields(obj)]

    if "." not in key:
        if key in ("pixel_pitch_m", "fill_factor"):
            return "sensor", key
        owner = next((table for table in OWNERS if key in fields(table)), None)
        if owner is None:
            names = ["pixel_pitch_m", "fill_factor"] + [name for table in OWNERS for name in fields(table)]
            raise ConfigError(f"no sensor parameter {key!r}{suggest(key, names)}", source=source, key=key_name)
        return owner, key
    table, _, name = key.partition(".")
    if table not in QUALIFIED_TABLES:
        raise ConfigError(f"no preset table {table!r}{suggest(table, QUALIFIED_TABLES)}; qualified names are "
                          f"table.field with table one of {', '.join(QUALIFIED_TABLES)}", source=source, key=key_name)
    if table == "aps" and parts["aps"] is None:
        raise ConfigError("this preset has no [aps] (no frame sensor) to override", source=source, key=key_name)
    names = list(SENSOR_FIELDS) if table == "sensor" else fields(table) + (["cutoff_ref_lux"] if table ==
                                                                          "photoreceptor" else [])
    if name not in names:
        raise ConfigError(f"no parameter {name!r} in [{table}]{suggest(name, names)}", source=source, key=key_name)
    return table, name


def _sensor_value(name: str, value: Any, *, source: str | None, key: str) -> Any:
    """A checked value of a sensor-level override (geometry, QE curve, the cutoff's reference light)."""
    if name in ("pixel_pitch_m", "fill_factor", "cutoff_ref_lux"):
        upper = {"pixel_pitch_m": 1e-3, "fill_factor": 1.0, "cutoff_ref_lux": MAX_CUTOFF_REF_LUX}[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= upper:
            raise ConfigError(f"expected a number in (0, {upper}], got {value!r}", source=source, key=key)
        return float(value)
    if name == "quantum_efficiency":
        from gevsim.optics import QE_CURVES

        if not isinstance(value, str) or value not in QE_CURVES:
            raise ConfigError(f"unknown quantum_efficiency {value!r}{suggest(str(value), QE_CURVES)}; choose from "
                              f"{', '.join(QE_CURVES)}", source=source, key=key)
        return value
    if not isinstance(value, str):
        raise ConfigError(f"expected a lamp spectrum name such as 'D65', got {value!r}", source=source, key=key)
    return value


def check_dark_current(photoreceptor: PhotoreceptorParams, noise: NoiseParams, *, source: str | None,
                       key: str) -> None:
    """A sensor's dark current must be > 0 at its temperature: the photoreceptor responds to
    ln(I_ph + I_dark), and a black pixel (I_ph = 0) has no finite response without it. (The pixel
    model itself takes 0 where every photocurrent is positive, as analytic tests use.)"""
    from gevsim.pixel.mechanisms.dark_current import dark_current_a

    dark = dark_current_a(noise, photoreceptor.temperature_k)
    if not dark > 0:
        at = "" if noise.dark_current_a == 0 else (f" at temperature_k = {photoreceptor.temperature_k:g} "
                                                    f"(dark_current_a = {noise.dark_current_a:g} A halving every "
                                                    f"{noise.dark_current_doubling_k:g} K below 300 K)")
        raise ConfigError(f"the dark current is {dark:g} A{at}; it must be > 0: the photoreceptor's response is "
                          "ln(I_ph + I_dark), and a black pixel has I_ph = 0", source=source, key=key)
    from scipy.constants import elementary_charge

    from gevsim._portable import exp_scalar

    spread = noise.dark_current_spread
    median = dark * float(exp_scalar(-0.5 * spread * spread))  # the lognormal DSNU keeps the mean
    if median < elementary_charge * MIN_DARK_ELECTRONS_PER_S:
        raise ConfigError(f"the median pixel's dark current is {median:.3g} A ({median / elementary_charge:.3g} "
                          f"electrons/s) at temperature_k = {photoreceptor.temperature_k:g}; it must be at least "
                          f"{MIN_DARK_ELECTRONS_PER_S:g} electron/s ({elementary_charge * MIN_DARK_ELECTRONS_PER_S:.3g}"
                          " A): below that it is single electrons seconds apart, not the continuous current that the "
                          "model's ln(I_ph + I_dark) and shot noise assume", source=source, key=key)


def preset_names() -> dict[str, Path]:
    """Names of the shipped sensor presets and their files."""
    return resource_tomls("noise")


def preset_path(name_or_path: str | Path) -> Path:
    """The file of a preset name (``davis346``) or TOML path (ConfigError for an unknown name)."""
    path = Path(name_or_path)
    if path.suffix != ".toml":
        names = preset_names()
        if str(name_or_path) not in names:
            raise ConfigError(f"unknown sensor preset {str(name_or_path)!r}{suggest(str(name_or_path), names)}; "
                              f"presets: {', '.join(names)}")
        path = names[str(name_or_path)]
    return path


def preset_digest(name_or_path: str | Path) -> str:
    """sha256 of a preset file's bytes: what a finished run's identity records, so that editing a preset
    makes the runs that used it compute again (a name or a path alone would not change)."""
    import hashlib

    path = preset_path(name_or_path)
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as exc:
        raise ConfigError(f"cannot read the sensor preset: {exc.strerror or exc}", source=str(path)) from None


def load_preset(name_or_path: str | Path) -> SensorPreset:
    """Load a preset by name (``dvs128``, ``davis346``, ``imx636``, ``ideal``) or TOML path."""
    return _load_preset(name_or_path, photometry=True)


def listed_preset(name_or_path: str | Path) -> SensorPreset:
    """A preset as ``gevsim presets`` lists it: read and checked as :func:`load_preset` does but for the two
    steps that import colour-science and numba (a second or more, issue 37): ``cutoff_ref_lux`` is not
    converted to a photocurrent (``photoreceptor.cutoff_ref_photocurrent_a`` keeps its default) and the dark
    current is not checked at the sensor's temperature. For listings, not for emulation."""
    return _load_preset(name_or_path, photometry=False)


def _load_preset(name_or_path: str | Path, *, photometry: bool) -> SensorPreset:
    path = preset_path(name_or_path)
    src = str(path)
    raw, r = load_table(path, what="sensor preset file", tables=TABLES)
    for table in ("sensor", "photoreceptor", "noise", "events"):
        if not isinstance(raw.get(table), dict):
            raise ConfigError(f"missing table [{table}]", source=src, key=table)
    sensor = dict(raw["sensor"])
    check_keys(sensor, SENSOR_KEYS, source=src, where="sensor")
    for key in ("width", "height"):  # at most 1e5 px a side, beyond any sensor (IMX636: 1280 x 720)
        r.number(sensor, key, "sensor", positive=True, integer=True, maximum=100_000)
    for key, upper in (("pixel_pitch_m", 1e-3), ("fill_factor", 1.0)):
        r.number(sensor, key, "sensor", positive=True, maximum=upper)
    from gevsim.optics import QE_CURVES

    qe_name = sensor.get("quantum_efficiency", "fsi")
    if not isinstance(qe_name, str) or qe_name not in QE_CURVES:
        raise ConfigError(f"unknown quantum_efficiency {qe_name!r}{suggest(str(qe_name), QE_CURVES)}; choose from "
                          f"{', '.join(QE_CURVES)}", source=src, key="sensor.quantum_efficiency")
    spectrum = sensor.get("bandwidth_reference_spectrum", "D65")
    if not isinstance(spectrum, str):
        r.fail("sensor.bandwidth_reference_spectrum", f"expected a lamp spectrum name such as 'D65', got {spectrum!r}")
    receptor = dict(raw["photoreceptor"])
    lux = receptor.get("cutoff_ref_lux")
    if lux is not None:
        lux = receptor.pop("cutoff_ref_lux")
        if "cutoff_ref_photocurrent_a" in receptor:
            raise ConfigError("give cutoff_ref_lux or cutoff_ref_photocurrent_a, not both", source=src,
                              key="photoreceptor.cutoff_ref_lux")
        r.number(raw["photoreceptor"], "cutoff_ref_lux", "photoreceptor", positive=True,
                 maximum=MAX_CUTOFF_REF_LUX)
        if photometry:
            receptor["cutoff_ref_photocurrent_a"] = lux_to_photocurrent_a(
                lux, pixel_pitch_m=sensor["pixel_pitch_m"], fill_factor=sensor["fill_factor"],
                spectrum=spectrum, source=src, qe=QE_CURVES[qe_name])
    aps = raw.get("aps")
    photoreceptor = PhotoreceptorParams.from_table(receptor, source=src)
    noise = NoiseParams.from_table(raw["noise"], source=src)
    if photometry:
        check_dark_current(photoreceptor, noise, source=src, key="noise.dark_current_a")
    return SensorPreset(
        name=str(sensor.get("name", path.stem)),
        description=str(sensor.get("description", "")),
        width=sensor["width"],
        height=sensor["height"],
        pixel_pitch_m=float(sensor["pixel_pitch_m"]),
        fill_factor=float(sensor["fill_factor"]),
        photoreceptor=photoreceptor,
        noise=noise,
        events=EventParams.from_table(raw["events"], source=src),
        aps=None if aps is None else ApsParams.from_table(aps, source=src),
        source=src,
        readout=ReadoutParams.from_table(raw.get("readout", {}), source=src),
        quantum_efficiency=qe_name,
        stated=StatedBehaviour.from_table(raw.get("stated", {}), source=src),
        bandwidth_reference_spectrum=spectrum,
        cutoff_ref_lux=None if lux is None else float(lux),
        assumed=parse_assumed(raw.get("assumed"), raw, source=src),
    )


def lux_to_photocurrent_a(lux: float, *, pixel_pitch_m: float, fill_factor: float, spectrum: str = "D65",
                          source: str | None = None, qe: Any = None) -> float:
    """Photocurrent of one pixel at a focal-plane illuminance, for a lamp spectrum and a silicon QE
    (None: the default FSI curve)."""
    from gevsim.optics import lamp_spectrum, responsivity_a_per_lm

    sd = lamp_spectrum(spectrum, source=source, key="sensor.bandwidth_reference_spectrum")
    return float(lux * pixel_pitch_m * pixel_pitch_m * fill_factor * responsivity_a_per_lm(sd, qe=qe))

