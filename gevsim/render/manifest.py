"""Scene manifests: the TOML file that names a scene's light groups, their
waveforms and emission, the camera trajectory, moving objects, resolution,
spp and duration.

A manifest points at a scene *builder*, a Python file with a
``build(options) -> dict`` function returning Mitsuba shapes and emitters
(geometry and materials only; gevsim adds the camera, film and integrator).
``[scene] extends = "other.toml"`` starts from another manifest and overrides
its tables key by key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gevsim.config import TomlReader, read_toml, resource_tomls
from gevsim.errors import ConfigError, check_keys, suggest
from gevsim.illumination import Waveform, from_spec as waveform_from_spec


TABLES = ("scene", "render", "sequence", "camera", "motion", "light_groups", "optics")
SCENE_KEYS = ("name", "description", "builder", "options", "extends")
QUALITY_KEYS = ("noise_target_ln", "noise_percentile", "max_spp", "time_budget_s", "sampler", "noise_floor_rel",
                "noise_metric", "denoise")
NOISE_METRICS = ("flicker", "absolute")  # see gevsim.render.convergence
RENDER_KEYS = ("width", "height", "spp", "seed", "flavour", "max_depth", "max_px_per_pose") + QUALITY_KEYS
#: ``[render]`` keys that emulation, study and dataset configs may override.
OVERRIDE_KEYS = ("width", "height", "spp", "seed", "max_px_per_pose") + QUALITY_KEYS
#: Mitsuba samplers a scene may use (``[render] sampler``).
SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")
SEQUENCE_KEYS = ("duration_s",)
CAMERA_KEYS = ("fov_deg", "keyframes")
CAMERA_KEY_KEYS = ("t_s", "origin", "target", "up")
MOTION_KEYS = ("object", "axis", "keyframes")
MOTION_KEY_KEYS = ("t_s", "translate_m", "rotate_deg")
GROUP_KEYS = ("emitters", "waveform", "spectrum", "radiance_w_m2_sr", "luminance_cd_m2", "illuminance_lux", "at_m")


@dataclass(frozen=True)
class Emission:
    """How bright a light group's emitters are (see :func:`gevsim.render.scene.emitter_rgb`).

    Exactly one of ``radiance_w_m2_sr`` (RGB, photopic-equivalent radiance),
    ``luminance_cd_m2`` (with a lamp ``spectrum``) or ``illuminance_lux`` at
    ``at_m`` metres on the emitter's axis (with a ``spectrum``).
    """

    spectrum: str | None = None
    radiance_w_m2_sr: tuple[float, float, float] | None = None
    luminance_cd_m2: float | None = None
    illuminance_lux: float | None = None
    at_m: float | None = None


@dataclass(frozen=True)
class LightGroup:
    name: str
    emitters: tuple[str, ...]
    waveform: Waveform
    emission: Emission


@dataclass(frozen=True)
class CameraKey:
    t_s: float
    origin: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)


@dataclass(frozen=True)
class ObjectKey:
    t_s: float
    translate_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotate_deg: float = 0.0


@dataclass(frozen=True)
class Motion:
    """Rigid motion of scene objects (moving together): translation, and rotation about
    ``axis`` through the centre of their joint bounding box. ``name`` identifies it."""

    objects: tuple[str, ...]
    keyframes: tuple[ObjectKey, ...]
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)


@dataclass(frozen=True)
class RenderSettings:
    """How a scene is rendered.

    Two modes. *Fixed*: ``spp`` samples per pixel (drafts). *Noise target*
    (when ``noise_target_ln`` is set): render in independent batches until the
    ``noise_percentile`` percentile over pixels of the standard error of
    ln(luminance), for the lamp mixtures the waveforms reach, is at most
    ``noise_target_ln``, or ``max_spp`` / ``time_budget_s`` is reached (see
    :mod:`gevsim.render.convergence`). ``noise_target_ln = "auto"`` is 0.4 x
    the smallest event threshold of the sensor an emulation uses (0.4 x 0.05 ln
    when rendering alone; the fraction is measured, see ``AUTO_TARGET_FRACTION``). ``noise_floor_rel`` keeps near-black pixels from
    dominating: the error is taken relative to (value + noise_floor_rel x the
    mixture's mean). ``noise_metric`` chooses the error measured: of the change
    of ln luminance between lamp mixtures (``"flicker"``, default) or of ln
    luminance itself (``"absolute"``). ``denoise = true`` passes the finished
    group images through Intel Open Image Denoise (:mod:`gevsim.render.denoise`):
    biased, off by default; its bias is measured in ``benchmarks/README.md``.
    """

    width: int = 346
    height: int = 260
    spp: int = 16
    seed: int = 0
    flavour: str = "rgb"
    max_depth: int = 5
    max_px_per_pose: float = 1.0
    noise_target_ln: float | str | None = None
    noise_percentile: float = 99.0
    max_spp: int = 16384
    time_budget_s: float | None = None
    sampler: str = "multijitter"
    noise_floor_rel: float = 1e-3
    noise_metric: str = "flicker"
    denoise: bool = False

    @property
    def targeted(self) -> bool:
        """Whether this is the noise-target mode (else a fixed ``spp``)."""
        return self.noise_target_ln is not None


@dataclass(frozen=True)
class SceneManifest:
    """A validated scene manifest."""

    name: str
    source: str
    builder: Path
    options: dict
    render: RenderSettings
    duration_s: float
    fov_deg: float
    camera: tuple[CameraKey, ...]
    motion: tuple[Motion, ...]
    light_groups: tuple[LightGroup, ...]
    optics: dict = field(default_factory=dict)
    description: str = ""
    raw: dict = field(default_factory=dict, repr=False)

    @property
    def group_names(self) -> tuple[str, ...]:
        return tuple(g.name for g in self.light_groups)

    @property
    def moving_objects(self) -> tuple[str, ...]:
        return tuple(o for m in self.motion for o in m.objects)

    @property
    def moving(self) -> bool:
        return len(self.camera) > 1 or bool(self.motion)


def builtin_scenes() -> dict[str, Path]:
    """Names of the built-in scenes and their manifest paths."""
    return resource_tomls("scenes")


def resolve(scene: str | Path) -> Path:
    """A manifest path from a path or the name of a built-in scene."""
    path = Path(scene)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise ConfigError("no such scene manifest", source=str(path))
        return path
    scenes = builtin_scenes()
    if str(scene) not in scenes:
        raise ConfigError(
            f"no scene manifest {str(scene)!r}{suggest(str(scene), scenes)}; built-in scenes: {', '.join(scenes)}"
        )
    return scenes[str(scene)]


def _read_toml(path: Path, chain: tuple[Path, ...] = ()) -> dict:
    data = read_toml(path, what="scene manifest")
    base = data.get("scene", {}).get("extends")
    if base is None:
        return data
    parent = (path.parent / base).resolve()
    if parent in chain:
        raise ConfigError(f"'extends' loops back to {parent}", source=str(path), key="scene.extends")
    merged = _read_toml(parent, chain + (parent,))
    for table, value in data.items():
        if isinstance(value, dict) and isinstance(merged.get(table), dict):
            merged[table] = {**merged[table], **value}
        else:
            merged[table] = value
    # Relative paths in the base (builder) stay relative to the base file.
    if "builder" not in data.get("scene", {}) and "builder" in merged.get("scene", {}):
        merged["scene"]["builder"] = str((parent.parent / merged["scene"]["builder"]).resolve())
    merged["scene"].pop("extends", None)
    return merged


def load(scene: str | Path) -> SceneManifest:
    """Load and validate a scene manifest (a path or a built-in scene name)."""
    path = resolve(scene)
    raw = _read_toml(path, (path.resolve(),))
    r = TomlReader(str(path))
    check_keys(raw, TABLES, source=r.source, where="")

    sc = r.table(raw, "scene")
    check_keys(sc, SCENE_KEYS, source=r.source, where="scene")
    if "builder" not in sc:
        r.fail("scene.builder", "missing: name the Python file with the scene's build(options) function")
    builder = (path.parent / sc["builder"]).resolve()
    if not builder.is_file():
        r.fail("scene.builder", f"no such file {builder}")
    options = sc.get("options", {})
    if not isinstance(options, dict):
        r.fail("scene.options", f"expected a table, got {options!r}")

    rt = r.table(raw, "render")
    check_keys(rt, RENDER_KEYS, source=r.source, where="render")
    d = RenderSettings()
    render = RenderSettings(
        width=r.number(rt, "width", "render", d.width, positive=True, integer=True),
        height=r.number(rt, "height", "render", d.height, positive=True, integer=True),
        spp=r.number(rt, "spp", "render", d.spp, positive=True, integer=True),
        seed=r.number(rt, "seed", "render", d.seed, minimum=0, integer=True),
        flavour=str(rt.get("flavour", d.flavour)),
        max_depth=r.number(rt, "max_depth", "render", d.max_depth, positive=True, integer=True),
        max_px_per_pose=float(r.number(rt, "max_px_per_pose", "render", d.max_px_per_pose, positive=True)),
        **quality_settings(rt, r, "render"),
    )
    if render.flavour not in ("rgb", "mono", "spectral"):
        r.fail("render.flavour", f"expected 'rgb', 'mono' or 'spectral', got {render.flavour!r}")

    seq = r.table(raw, "sequence")
    check_keys(seq, SEQUENCE_KEYS, source=r.source, where="sequence")
    duration_s = float(r.number(seq, "duration_s", "sequence", positive=True))

    cam = r.table(raw, "camera")
    check_keys(cam, CAMERA_KEYS, source=r.source, where="camera")
    fov_deg = float(r.number(cam, "fov_deg", "camera", 60.0, positive=True))
    if fov_deg >= 180:
        r.fail("camera.fov_deg", f"must be < 180, got {fov_deg}")
    camera = []
    for i, key in enumerate(cam.get("keyframes", [])):
        where = f"camera.keyframes[{i}]"
        check_keys(key, CAMERA_KEY_KEYS, source=r.source, where=where)
        camera.append(
            CameraKey(
                t_s=float(r.number(key, "t_s", where, 0.0, minimum=0.0)),
                origin=r.vector(key, "origin", where),
                target=r.vector(key, "target", where),
                up=r.vector(key, "up", where, (0.0, 1.0, 0.0)),
            )
        )
    if not camera:
        r.fail("camera.keyframes", "at least one keyframe (origin, target) is needed")
    _check_times([k.t_s for k in camera], r, "camera.keyframes")
    for i, key in enumerate(camera):
        if np.allclose(key.origin, key.target):
            r.fail(f"camera.keyframes[{i}]", "origin and target coincide")

    motion = []
    for i, mo in enumerate(raw.get("motion", [])):
        where = f"motion[{i}]"
        check_keys(mo, MOTION_KEYS, source=r.source, where=where)
        objects = mo.get("object")
        objects = [objects] if isinstance(objects, str) else objects
        if not isinstance(objects, list) or not objects or not all(isinstance(o, str) for o in objects):
            r.fail(f"{where}.object", f"expected the id (or a list of ids) of the moving shapes, got {objects!r}")
        keys = []
        for j, key in enumerate(mo.get("keyframes", [])):
            kw = f"{where}.keyframes[{j}]"
            check_keys(key, MOTION_KEY_KEYS, source=r.source, where=kw)
            keys.append(
                ObjectKey(
                    t_s=float(r.number(key, "t_s", kw, minimum=0.0)),
                    translate_m=r.vector(key, "translate_m", kw, (0.0, 0.0, 0.0)),
                    rotate_deg=float(r.number(key, "rotate_deg", kw, 0.0)),
                )
            )
        if not keys:
            r.fail(f"{where}.keyframes", "at least one keyframe is needed")
        _check_times([k.t_s for k in keys], r, f"{where}.keyframes")
        axis = r.vector(mo, "axis", where, (0.0, 1.0, 0.0))
        if np.linalg.norm(axis) == 0:
            r.fail(f"{where}.axis", "must not be the zero vector")
        motion.append(Motion(objects=tuple(objects), keyframes=tuple(keys), axis=axis))

    groups = []
    lg = r.table(raw, "light_groups")
    if not lg:
        r.fail("light_groups", "at least one light group is needed")
    for name, spec in lg.items():
        groups.append(_light_group(name, spec, r))
    seen = {}
    for g in groups:
        for e in g.emitters:
            if e in seen:
                r.fail(f"light_groups.{g.name}.emitters", f"emitter {e!r} is already in light group {seen[e]!r}")
            seen[e] = g.name

    optics = r.table(raw, "optics")
    return SceneManifest(
        name=str(sc.get("name", path.stem)),
        source=r.source,
        builder=builder,
        options=options,
        render=render,
        duration_s=duration_s,
        fov_deg=fov_deg,
        camera=tuple(camera),
        motion=tuple(motion),
        light_groups=tuple(groups),
        optics=optics,
        description=str(sc.get("description", "")),
        raw=raw,
    )


def check_render_overrides(table: dict, r: TomlReader, where: str) -> None:
    """Validate a ``[render]`` override table of an emulation, study or dataset config."""
    check_keys(table, OVERRIDE_KEYS, source=r.source, where=where)
    for key in ("width", "height", "spp"):
        if key in table:
            r.number(table, key, where, positive=True, integer=True)
    if "seed" in table:
        r.number(table, "seed", where, minimum=0, integer=True)
    if "max_px_per_pose" in table:
        r.number(table, "max_px_per_pose", where, positive=True)
    quality_settings(table, r, where)


def quality_settings(table: dict, r: TomlReader, where: str) -> dict:
    """The render-quality keys of a ``[render]`` table, validated (errors name the key)."""
    out = {}
    if "spp" in table and "noise_target_ln" in table:
        r.fail(f"{where}.spp", "give either spp (a fixed sample count, for drafts) or noise_target_ln "
                               "(render until the noise target is met), not both")
    if "noise_target_ln" in table:
        target = table["noise_target_ln"]
        if target != "auto":
            target = float(r.number(table, "noise_target_ln", where, positive=True))
        out["noise_target_ln"] = target
    if "noise_percentile" in table:
        p = float(r.number(table, "noise_percentile", where, positive=True))
        if p > 100:
            r.fail(f"{where}.noise_percentile", f"must be in (0, 100], got {p!r}")
        out["noise_percentile"] = p
    if "max_spp" in table:
        out["max_spp"] = r.number(table, "max_spp", where, minimum=1, integer=True)
    if "time_budget_s" in table:
        out["time_budget_s"] = float(r.number(table, "time_budget_s", where, positive=True))
    if "noise_floor_rel" in table:
        out["noise_floor_rel"] = float(r.number(table, "noise_floor_rel", where, positive=True))
    if "denoise" in table:
        if not isinstance(table["denoise"], bool):
            r.fail(f"{where}.denoise", f"expected true or false, got {table['denoise']!r}")
        out["denoise"] = table["denoise"]
    for key, what, options in (("noise_metric", "noise metric", NOISE_METRICS), ("sampler", "sampler", SAMPLERS)):
        if key in table:
            value = table[key]
            if value not in options:
                r.fail(f"{where}.{key}", f"unknown {what} {value!r}{suggest(str(value), options)}; "
                                         f"one of {', '.join(options)}")
            out[key] = value
    return out


def _check_times(times, r: TomlReader, where: str) -> None:
    if any(b <= a for a, b in zip(times, times[1:])):
        r.fail(where, f"keyframe times must increase strictly, got {times}")


def _light_group(name: str, spec: dict, r: TomlReader) -> LightGroup:
    where = f"light_groups.{name}"
    if not isinstance(spec, dict):
        r.fail(where, f"expected a table, got {spec!r}")
    check_keys(spec, GROUP_KEYS, source=r.source, where=where)
    emitters = spec.get("emitters")
    if not isinstance(emitters, list) or not emitters or not all(isinstance(e, str) for e in emitters):
        r.fail(f"{where}.emitters", f"expected a non-empty list of emitter ids, got {emitters!r}")
    wf = spec.get("waveform", {"type": "dc"})
    if not isinstance(wf, dict):
        r.fail(f"{where}.waveform", f"expected a table such as {{type = 'pwm', ...}}, got {wf!r}")
    waveform = waveform_from_spec(wf, source=r.source, key=f"{where}.waveform")
    modes = [k for k in ("radiance_w_m2_sr", "luminance_cd_m2", "illuminance_lux") if k in spec]
    if len(modes) != 1:
        r.fail(where, "give exactly one of radiance_w_m2_sr, luminance_cd_m2 or illuminance_lux (with at_m)")
    spectrum = spec.get("spectrum")
    if spectrum is not None and not isinstance(spectrum, str):
        r.fail(f"{where}.spectrum", f"expected a lamp spectrum name, got {spectrum!r}")
    if modes[0] != "radiance_w_m2_sr" and spectrum is None:
        r.fail(f"{where}.spectrum", f"{modes[0]} needs a lamp spectrum (e.g. 'FL2', 'HP1', 'LED-B3', 'D65')")
    if spectrum is not None:
        from gevsim.optics import lamp_spectrum

        try:
            lamp_spectrum(spectrum)
        except ConfigError as exc:
            r.fail(f"{where}.spectrum", str(exc))
    emission = Emission(
        spectrum=spectrum,
        radiance_w_m2_sr=r.vector(spec, "radiance_w_m2_sr", where, nonnegative=True) if modes[0] == "radiance_w_m2_sr" else None,
        luminance_cd_m2=float(r.number(spec, "luminance_cd_m2", where, minimum=0.0)) if modes[0] == "luminance_cd_m2" else None,
        illuminance_lux=float(r.number(spec, "illuminance_lux", where, minimum=0.0)) if modes[0] == "illuminance_lux" else None,
        at_m=float(r.number(spec, "at_m", where, positive=True)) if modes[0] == "illuminance_lux" else None,
    )
    return LightGroup(name=str(name), emitters=tuple(emitters), waveform=waveform, emission=emission)


def override(manifest: SceneManifest, *, source: str | None = None, **changes) -> SceneManifest:
    """A copy with render settings (``[render]`` keys) or ``duration_s`` replaced;
    ``None`` values are ignored. ``raw`` follows suit.

    Giving ``spp`` without ``noise_target_ln`` switches to the fixed mode;
    giving ``noise_target_ln`` switches to the noise-target mode. ``source``
    names the file the changes come from, for error messages.
    """
    import copy
    import dataclasses

    changes = {k: v for k, v in changes.items() if v is not None}
    raw = copy.deepcopy(manifest.raw)
    duration = changes.pop("duration_s", manifest.duration_s)
    if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not duration > 0 \
            or not math.isfinite(duration):
        raise ConfigError(f"duration must be > 0, got {duration!r}", source=source, key="duration_s")
    for key, value in changes.items():
        if key not in RENDER_KEYS:
            raise ConfigError(f"cannot override {key!r}{suggest(key, RENDER_KEYS)}", source=source, key=key)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and key != "seed" and value <= 0:
            raise ConfigError(f"must be > 0, got {value!r}", source=source, key=f"render.{key}")
    changes.update(quality_settings(changes, TomlReader(source or "overrides"), "render"))
    render = raw.setdefault("render", {})
    if "spp" in changes:  # a fixed sample count: the draft mode
        changes["noise_target_ln"] = None
        render.pop("noise_target_ln", None)
    if changes.get("noise_target_ln") is not None:
        render.pop("spp", None)
    render.update({k: v for k, v in changes.items() if v is not None})
    raw.setdefault("sequence", {})["duration_s"] = duration
    return dataclasses.replace(
        manifest, render=dataclasses.replace(manifest.render, **changes), duration_s=duration, raw=raw
    )
