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

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gevsim.config import TomlReader, read_toml, resource_tomls
from gevsim.errors import ConfigError, check_keys, clipped, suggest
from gevsim.illumination import Waveform
from gevsim.illumination import from_spec as waveform_from_spec
from gevsim.io.ownership import check_name
from gevsim.optics.lamps import LAMP_NAMES  # the names only: colour-science where one is not there
from gevsim.render.manifest_checks import brightest, check_up
from gevsim.render.quality import RENDER_KEYS, RenderSettings, check_render_size, quality_settings, render_settings
from gevsim.render.quality import check_render_overrides as check_render_overrides  # re-exported (it lived here)
from gevsim.resources import MAX_SPP

TABLES = ("scene", "render", "sequence", "camera", "motion", "light_groups", "optics")
SCENE_KEYS = ("name", "description", "builder", "options", "extends")
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
    #: This manifest and every manifest it ``extends``, resolved (what :mod:`gevsim.render.inputs` hashes).
    manifests: tuple[Path, ...] = ()

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
    try:  # a name too long for the file system is no manifest either
        if path.suffix == ".toml" or path.exists():
            if not path.is_file():
                raise ConfigError("no such scene manifest", source=clipped(str(path)))
            return path
    except OSError as exc:
        raise ConfigError(f"no such scene manifest ({exc.strerror or exc})", source=clipped(str(scene))) from None
    scenes = builtin_scenes()
    if str(scene) not in scenes:
        raise ConfigError(f"no scene manifest {clipped(str(scene))!r}{suggest(str(scene), scenes)}; "
                          f"built-in scenes: {', '.join(scenes)}")
    return scenes[str(scene)]


def _read_toml(path: Path, chain: tuple[Path, ...] = (), files: list[Path] | None = None) -> dict:
    """The manifest at ``path`` merged over the ones it extends; ``files`` collects every file read."""
    data = read_toml(path, what="scene manifest")
    if files is not None:
        files.append(path.resolve())
    scene = data.get("scene", {})
    if not isinstance(scene, dict):
        raise ConfigError(f"expected a table, got {scene!r}", source=str(path), key="scene")
    base = scene.get("extends")
    if base is None:
        return data
    if not isinstance(base, str):
        raise ConfigError(f"expected the path of the manifest this one extends, got {base!r}", source=str(path),
                          key="scene.extends")
    parent = (path.parent / base).resolve()
    if parent in chain:
        raise ConfigError(f"'extends' loops back to {parent}", source=str(path), key="scene.extends")
    merged = _read_toml(parent, chain + (parent,), files)
    for table, value in data.items():
        if isinstance(value, dict) and isinstance(merged.get(table), dict):
            if table == "render" and ("spp" in value) != ("noise_target_ln" in value):
                # The child's quality mode replaces the base's, as override() does (issue 24 #18).
                merged[table].pop("noise_target_ln" if "spp" in value else "spp", None)
            merged[table] = {**merged[table], **value}
        else:
            merged[table] = value
    # Relative paths in the base (builder) stay relative to the base file.
    if "builder" not in scene and isinstance(merged["scene"].get("builder"), str):
        merged["scene"]["builder"] = str((parent.parent / merged["scene"]["builder"]).resolve())
    merged["scene"].pop("extends", None)
    return merged


def load(scene: str | Path) -> SceneManifest:
    """Load and validate a scene manifest (a path or a built-in scene name)."""
    path = resolve(scene)
    manifests: list[Path] = []
    raw = _read_toml(path, (path.resolve(),), manifests)
    r = TomlReader(str(path))
    check_keys(raw, TABLES, source=r.source, where="")

    sc = r.table(raw, "scene")
    check_keys(sc, SCENE_KEYS, source=r.source, where="scene")
    builder = _builder(sc, path, r)
    options = sc.get("options", {})
    if not isinstance(options, dict):
        r.fail("scene.options", f"expected a table, got {options!r}")

    render = render_settings(r.table(raw, "render"), r)

    seq = r.table(raw, "sequence")
    check_keys(seq, SEQUENCE_KEYS, source=r.source, where="sequence")
    duration_s = float(r.number(seq, "duration_s", "sequence", positive=True))

    cam = r.table(raw, "camera")
    check_keys(cam, CAMERA_KEYS, source=r.source, where="camera")
    fov_deg, camera = _camera(cam, r)

    motion = _motions(raw, r)

    groups = _light_groups(raw, r)

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
        manifests=tuple(manifests),
    )


def _builder(sc: dict, path: Path, r: TomlReader) -> Path:
    """The scene's builder file (a Python build(options) or a Mitsuba XML scene), beside the manifest."""
    if "builder" not in sc:
        r.fail("scene.builder", "missing: name the Python file with the scene's build(options) function, or a "
                                "Mitsuba XML scene file")
    if not isinstance(sc["builder"], str):
        r.fail("scene.builder", f"expected the path of a Python builder (.py) or a Mitsuba XML scene (.xml), got "
                                f"{sc['builder']!r}")
    builder = (path.parent / sc["builder"]).resolve()
    if not builder.is_file():
        r.fail("scene.builder", f"no such file {builder}")
    if builder.suffix.lower() not in (".py", ".xml"):
        r.fail("scene.builder", f"expected a Python builder (.py) or a Mitsuba XML scene (.xml), got {builder.name}")
    return builder


def _camera(cam: dict, r: TomlReader) -> tuple[float, list[CameraKey]]:
    """The ``[camera]`` table: field of view (degrees) and keyframes, checked."""
    fov_deg = float(r.number(cam, "fov_deg", "camera", 60.0, positive=True))
    if fov_deg >= 180:
        r.fail("camera.fov_deg", f"must be < 180, got {fov_deg}")
    camera = []
    for i, key in enumerate(r.list(cam, "keyframes", "camera.", of=dict, item="a table {t_s, origin, target}")):
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
        check_up(key.origin, key.target, key.up, r, f"camera.keyframes[{i}].up")
    return fov_deg, camera


def _motions(raw: dict, r: TomlReader) -> list[Motion]:
    """The ``[[motion]]`` tables: moving shapes and their keyframes, checked."""
    motion = []
    for i, mo in enumerate(r.list(raw, "motion", of=dict, item="a [[motion]] table")):
        where = f"motion[{i}]"
        check_keys(mo, MOTION_KEYS, source=r.source, where=where)
        objects = mo.get("object")
        objects = [objects] if isinstance(objects, str) else objects
        if not isinstance(objects, list) or not objects or not all(isinstance(o, str) for o in objects):
            r.fail(f"{where}.object", f"expected the id (or a list of ids) of the moving shapes, got {objects!r}")
        keys = []
        for j, key in enumerate(r.list(mo, "keyframes", f"{where}.", of=dict, item="a table {t_s, translate_m, "
                                                                                  "rotate_deg}")):
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
    return motion


def _light_groups(raw: dict, r: TomlReader) -> list[LightGroup]:
    """The ``[light_groups.<name>]`` tables; an emitter may be in one group only."""
    groups = []
    lg = r.table(raw, "light_groups")
    if not lg:
        r.fail("light_groups", "at least one light group is needed")
    for name, spec in lg.items():
        groups.append(_light_group(name, spec, r))
    seen: dict[str, str] = {}
    for g in groups:
        for e in g.emitters:
            if e in seen:
                r.fail(f"light_groups.{g.name}.emitters", f"emitter {e!r} is already in light group {seen[e]!r}")
            seen[e] = g.name
    return groups


def _check_times(times, r: TomlReader, where: str) -> None:
    if any(b <= a for a, b in zip(times, times[1:])):
        r.fail(where, f"keyframe times must increase strictly, got {times}")


def _light_group(name: str, spec: dict, r: TomlReader) -> LightGroup:
    check_name(name, source=r.source, key="light_groups")  # a folder of the render's basis
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
    if spectrum is not None and spectrum not in LAMP_NAMES:  # another spelling colour-science takes, or none
        from gevsim.optics import lamp_spectrum

        try:
            lamp_spectrum(spectrum)
        except ConfigError as exc:
            r.fail(f"{where}.spectrum", str(exc))
    mode = modes[0]
    emission = Emission(
        spectrum=spectrum,
        radiance_w_m2_sr=r.vector(spec, mode, where, nonnegative=True) if mode == "radiance_w_m2_sr" else None,
        luminance_cd_m2=float(r.number(spec, mode, where, minimum=0.0)) if mode == "luminance_cd_m2" else None,
        illuminance_lux=float(r.number(spec, mode, where, minimum=0.0)) if mode == "illuminance_lux" else None,
        at_m=float(r.number(spec, "at_m", where, positive=True)) if mode == "illuminance_lux" else None,
    )
    brightest(mode, getattr(emission, mode), r, where)
    return LightGroup(name=str(name), emitters=tuple(emitters), waveform=waveform, emission=emission)


def override(manifest: SceneManifest, *, source: str | None = None, **changes: Any) -> SceneManifest:
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
    r = TomlReader(source or "overrides")
    r.number({"duration_s": duration}, "duration_s", "sequence", positive=True)
    for key, value in changes.items():
        if key not in RENDER_KEYS:
            raise ConfigError(f"cannot override {key!r}{suggest(key, RENDER_KEYS)}", source=source, key=key)
        if key == "seed":
            r.number(changes, key, "render", minimum=0, integer=True)
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            spp = key == "spp"  # a whole number of samples, at most MAX_SPP
            r.number(changes, key, "render", positive=True, integer=spp, maximum=MAX_SPP if spp else None)
    changes.update(quality_settings(changes, r, "render"))
    check_render_size(changes.get("width", manifest.render.width), changes.get("height", manifest.render.height), r,
                      "render")
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
