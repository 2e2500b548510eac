"""Build a Mitsuba scene from a manifest and drive it: poses and light groups.

The scene is loaded once (``optimize=False`` so moving shapes are not merged);
poses move the camera and objects, and light groups are switched by scaling
their emitters' radiance parameters through ``mitsuba.traverse``. Light
transport is linear in emitter radiance, so with the same seed the basis
images of the groups sum to the render with every group on.
"""

from __future__ import annotations

import hashlib
import logging
import math

import numpy as np

from gevsim.errors import ConfigError, suggest
from gevsim.render import backend, integrator
from gevsim.render.inputs import build_shapes, files_digest
from gevsim.render.inputs import load_builder as load_builder  # re-exported (it lived here)
from gevsim.render.manifest import Emission, LightGroup, SceneManifest
from gevsim.render.rays import PinholeGrid
from gevsim.render.trajectory import Pose, pose_at, pose_times
from gevsim.render.xml_scene import is_xml, object_emits, xml_inputs

log = logging.getLogger(__name__)

# Spectral emitters with zero radiance make Mitsuba fail ("no probability
# mass"); they are scaled by this factor instead (error ~ K * 1e-9, negligible).
SPECTRAL_OFF = 1e-9
#: Mitsuba plugin types that are emitters themselves (a shape emits through its ``emitter`` child).
EMITTER_TYPES = ("point", "spot", "area", "constant", "directional", "envmap")
_RADIANCE_PREFIXES = ("emitter.radiance.", "radiance.", "intensity.", "irradiance.")


def exact_count(sampler: str, spp: int) -> int:
    """The largest sample count <= ``spp`` that ``sampler`` takes without rounding (at least its minimum).

    Mitsuba's stratified and multijitter samplers take squares, ``ldsampler``
    squares that are powers of two (powers of 4), ``orthogonal`` squares of primes.
    """
    spp = max(1, int(spp))
    if sampler in ("stratified", "multijitter"):
        return math.isqrt(spp) ** 2
    if sampler == "ldsampler":
        return 4 ** max(1, int(math.log(spp, 4) + 1e-9))
    if sampler == "orthogonal":
        root = math.isqrt(spp)
        while root > 2 and any(root % d == 0 for d in range(2, math.isqrt(root) + 1)):
            root -= 1
        return max(2, root) ** 2
    return spp


def content_hash(manifest: SceneManifest) -> str:
    """Hash of everything that defines the scene's geometry, materials and emission (for an XML
    scene: the XML and every file it reads, :func:`~gevsim.render.xml_scene.xml_inputs`)."""
    h = hashlib.sha256()
    if is_xml(manifest.builder):
        for path in xml_inputs(manifest.builder, manifest.options):
            h.update(path.name.encode())
            h.update(path.read_bytes() if path.is_file() else b"<missing>")
    else:
        h.update(manifest.builder.read_bytes())
    h.update(repr(sorted(manifest.options.items())).encode())
    for g in manifest.light_groups:
        h.update(repr((g.name, g.emitters, g.emission)).encode())
    r = manifest.render
    h.update(repr((r.width, r.height, r.max_depth, manifest.fov_deg)).encode())
    return h.hexdigest()


def emitting_area_m2(entry: dict, emitter_id: str, source: str) -> float:
    """Area facing the axis of a rectangle, disk or sphere emitter, from its ``to_world``."""
    import mitsuba as mi

    m = np.array(entry.get("to_world", mi.ScalarTransform4f()).matrix, float).reshape(4, 4)
    c0, c1 = m[:3, 0], m[:3, 1]
    kind = entry.get("type")
    if kind == "rectangle":
        return 4.0 * float(np.linalg.norm(np.cross(c0, c1)))
    if kind == "disk":
        return math.pi * float(np.linalg.norm(c0) * np.linalg.norm(c1))
    if kind == "sphere":
        return math.pi * (entry.get("radius", 1.0) * float(np.linalg.norm(c0))) ** 2
    raise ConfigError(
        f"illuminance_lux needs a rectangle, disk or sphere emitter; {emitter_id!r} is a {kind!r}",
        source=source,
        key="light_groups",
    )


def emitter_rgb(emission: Emission, *, area_m2: float | None = None) -> tuple[float, float, float]:
    """RGB photopic-equivalent radiance (W/(m^2 sr), Y = luminance / 683) of an emitter.

    ``illuminance_lux`` at ``at_m`` on the axis of a small Lambertian source of
    area A: E = L A / d^2, so L = E d^2 / A.
    """
    from gevsim.optics import lamp_spectrum, spectrum_to_rgb

    if emission.radiance_w_m2_sr is not None:
        r, g, b = (float(v) for v in emission.radiance_w_m2_sr)
        return r, g, b
    luminance = emission.luminance_cd_m2
    if luminance is None:  # the manifest checked: illuminance at a distance, and a spectrum
        assert emission.illuminance_lux is not None and emission.at_m is not None and area_m2 is not None
        luminance = emission.illuminance_lux * emission.at_m**2 / area_m2
    assert emission.spectrum is not None
    r, g, b = (float(v) for v in np.asarray(spectrum_to_rgb(lamp_spectrum(emission.spectrum),
                                                            luminance_cd_m2=luminance)).ravel())
    return r, g, b


class MitsubaScene:
    """A loaded scene with pose and light-group control.

    Parameters
    ----------
    manifest : the validated scene manifest.
    variant : a :class:`~gevsim.render.backend.VariantChoice`; chosen with
        :func:`~gevsim.render.backend.activate` when omitted.
    """

    def __init__(self, manifest: SceneManifest, *, variant: backend.VariantChoice | None = None):
        self.manifest = manifest
        self.variant = variant or backend.activate(manifest.render.flavour)
        import mitsuba as mi

        mi.set_variant(self.variant.variant)
        self._mi = mi
        self._object_emission: dict[str, tuple[float, float, float]] = {}
        shapes, self.builder_files = build_shapes(manifest)  # a Python builder's dict or an XML scene's objects
        self.scene_dict = self._assemble(shapes)
        try:
            self.scene = mi.load_dict(self.scene_dict, optimize=False)
        except Exception as exc:
            raise ConfigError(f"Mitsuba could not load the scene: {exc}", source=str(manifest.builder)) from exc
        self.params = mi.traverse(self.scene)
        self._group_keys = self._find_group_keys()
        self._set_object_emission()
        self._group_emitters: list[list] | None = None
        self._original = {k: type(self.params[k])(self.params[k]) for keys in self._group_keys.values() for k in keys}
        self._rest: dict[str, tuple[str, np.ndarray]] = {}
        self.centres: dict[int, np.ndarray] = {}
        self._probe: dict[str | None, np.ndarray] = {None: self._scene_probe_points()}
        shapes_by_id = {s.id(): s for s in self.scene.shapes()}
        for i, motion in enumerate(manifest.motion):
            corners = []
            for obj in motion.objects:
                bbox = shapes_by_id[obj].bbox()
                lo, hi = np.array(bbox.min, float).ravel(), np.array(bbox.max, float).ravel()
                corners.append(np.array(np.meshgrid(*zip(lo, hi))).reshape(3, -1).T)
                self._probe[obj] = corners[-1]
                key = f"{obj}.to_world"
                if key in self.params:
                    self._rest[obj] = ("to_world", np.array(self.params[key].matrix, float).reshape(4, 4))
                else:
                    positions = np.array(self.params[f"{obj}.vertex_positions"], float).reshape(-1, 3)
                    self._rest[obj] = ("vertex_positions", positions)
            box = np.vstack(corners)
            self.centres[i] = 0.5 * (box.min(axis=0) + box.max(axis=0))

    # -- assembly ---------------------------------------------------------------
    def _assemble(self, shapes: dict) -> dict:
        mi, m = self._mi, self.manifest
        src = m.source
        ids = set(shapes)
        for group in m.light_groups:
            for eid in group.emitters:
                if eid not in shapes:
                    raise ConfigError(
                        f"light group {group.name!r} names no emitter {eid!r}{suggest(eid, ids)}",
                        source=src,
                        key=f"light_groups.{group.name}.emitters",
                    )
                entry = shapes[eid]
                if not isinstance(entry, dict):  # an object of an XML scene: its radiance is set once loaded
                    if group.emission.illuminance_lux is not None:
                        raise ConfigError(f"light group {group.name!r}: illuminance_lux needs a Python builder; "
                                          "give an XML scene's emitters luminance_cd_m2 or radiance_w_m2_sr",
                                          source=src, key=f"light_groups.{group.name}")
                    self._object_emission[eid] = emitter_rgb(group.emission)
                    continue
                area = emitting_area_m2(entry, eid, src) if group.emission.illuminance_lux is not None else None
                rgb = {"type": "rgb", "value": list(emitter_rgb(group.emission, area_m2=area))}
                if isinstance(entry.get("emitter"), dict):
                    entry["emitter"]["radiance"] = rgb
                elif entry.get("type") in ("point", "spot"):
                    entry["intensity"] = rgb
                elif entry.get("type") in ("area", "constant", "directional"):
                    entry["irradiance" if entry["type"] == "directional" else "radiance"] = rgb
                else:
                    raise ConfigError(
                        f"light group {group.name!r}: {eid!r} is not an emitter gevsim can drive", source=src,
                        key=f"light_groups.{group.name}.emitters",
                    )
        grouped = {e for g in m.light_groups for e in g.emitters}
        for sid, entry in shapes.items():
            emits = (isinstance(entry, dict) and ("emitter" in entry or entry.get("type") in EMITTER_TYPES)
                     or not isinstance(entry, dict) and object_emits(entry))
            if emits and sid not in grouped:
                raise ConfigError(
                    f"emitter {sid!r} belongs to no light group; add it to one so its waveform is known",
                    source=src,
                    key="light_groups",
                )
        for i, motion in enumerate(m.motion):
            for obj in motion.objects:
                if obj not in shapes:
                    raise ConfigError(
                        f"moving object {obj!r} is not in the scene{suggest(obj, ids)}",
                        source=src, key=f"motion[{i}].object",
                    )
        r = m.render
        pose0 = pose_at(m, {i: np.zeros(3) for i in range(len(m.motion))}, 0.0)
        return {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": r.max_depth},
            "sensor": {
                "type": "perspective",
                "fov": m.fov_deg,
                "fov_axis": "x",
                "to_world": mi.ScalarTransform4f(pose0.camera.tolist()),
                "film": {
                    "type": "hdrfilm",
                    "width": r.width,
                    "height": r.height,
                    "rfilter": {"type": "box"},
                    "pixel_format": "luminance" if r.flavour == "mono" else "rgb",
                },
                "sampler": {"type": r.sampler, "sample_count": 4},
            },
            **shapes,
        }

    def _set_object_emission(self) -> None:
        """Give the emitters of an XML scene their light group's radiance (a Python builder's get it in
        :meth:`_assemble`)."""
        if not self._object_emission:
            return
        for keys in self._group_keys.values():
            for key in keys:
                eid = key.split(".", 1)[0]
                if eid not in self._object_emission:
                    continue
                rgb = self._object_emission[eid]
                if key.endswith(".d65.values"):
                    raise ConfigError(f"emitter {eid!r}: spectral radiance in the XML scene; give it an <rgb> radiance",
                                      source=str(self.manifest.builder))
                value = self.params[key]
                channels = len(value) if hasattr(value, "__len__") else 1
                y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
                self.params[key] = type(value)(rgb if channels == 3 else y)
        self.params.update()

    def _find_group_keys(self) -> dict[str, list[str]]:
        keys = {}
        for group in self.manifest.light_groups:
            found = []
            for eid in group.emitters:
                mine = [k for k in self.params.keys() if any(k.startswith(f"{eid}.{p}") for p in _RADIANCE_PREFIXES)]
                spectral = [k for k in mine if k.endswith(".d65.values")]
                mine = spectral or [k for k in mine if k.endswith((".value", ".data"))]
                if not mine:
                    raise ConfigError(
                        f"light group {group.name!r}: emitter {eid!r} has no radiance parameter gevsim can scale",
                        source=self.manifest.source,
                        key=f"light_groups.{group.name}",
                    )
                found += mine
            keys[group.name] = found
        return keys

    def _scene_probe_points(self) -> np.ndarray:
        """Bounding-box corners and centres of every shape: what camera motion moves in the image."""
        pts = []
        for shape in self.scene.shapes():
            bbox = shape.bbox()
            lo, hi = np.array(bbox.min, float).ravel(), np.array(bbox.max, float).ravel()
            pts.append(0.5 * (lo + hi))
            pts.extend(np.array(np.meshgrid(*zip(lo, hi))).reshape(3, -1).T)
        return np.array(pts)

    @property
    def inputs_digest(self) -> str:
        """Content hash of the builder and every file it loaded (:mod:`gevsim.render.inputs`)."""
        return files_digest(self.builder_files, base=self.manifest.builder.parent)

    # -- control --------------------------------------------------------------------
    def pose_times(self) -> np.ndarray:
        return pose_times(self.manifest, self._probe, self.centres)

    def pose_at(self, t_s: float) -> Pose:
        return pose_at(self.manifest, self.centres, t_s)

    def set_pose(self, pose: Pose) -> None:
        mi, p = self._mi, self.params
        p["sensor.to_world"] = mi.AffineTransform4f(pose.camera)
        for obj, mat in pose.objects.items():
            kind, rest = self._rest[obj]
            if kind == "to_world":
                p[f"{obj}.to_world"] = mi.AffineTransform4f(mat @ rest)
            else:
                moved = rest @ mat[:3, :3].T + mat[:3, 3]
                p[f"{obj}.vertex_positions"] = type(p[f"{obj}.vertex_positions"])(moved.ravel())
        p.update()

    def set_groups(self, on: set[str] | None = None) -> None:
        """Switch light groups: those in ``on`` at full radiance, the rest off (all on when None)."""
        off = SPECTRAL_OFF if "spectral" in self.variant.variant else 0.0
        for name, keys in self._group_keys.items():
            scale = 1.0 if on is None or name in on else off
            for k in keys:
                self.params[k] = self._original[k] * scale
        self.params.update()

    @property
    def one_pass(self) -> bool:
        """Whether all light groups render in one pass (JIT variants), else one group at a time."""
        return integrator.supported(self.variant.variant)

    def sample_count(self, spp: int) -> int:
        """The samples per pixel the scene's sampler takes for ``spp``: ``spp`` itself when it is
        :func:`exact_count`, else Mitsuba's rounding (with its warning)."""
        if exact_count(self.manifest.render.sampler, spp) == spp:
            return int(spp)
        sampler = self.scene.sensors()[0].sampler().clone()
        sampler.set_sample_count(int(spp))
        return int(sampler.sample_count())

    def render_groups(self, *, spp: int, seed: int, one_pass: bool | None = None, grid: PinholeGrid | None = None,
                      pixels: np.ndarray | None = None) -> np.ndarray:
        """(K, H, W, C) radiance of every light group at the current pose, from ``spp`` samples.

        In JIT variants one set of paths serves all groups
        (:func:`gevsim.render.integrator.render_groups`); in scalar variants
        each group is rendered alone with Mitsuba's ``path`` and the same seed
        (``one_pass=False`` forces that, for comparisons). ``grid`` (a
        :class:`~gevsim.render.rays.PinholeGrid`, one-pass only) renders its cells instead of the film, and
        ``pixels`` (flat indices into it) only those cells.
        """
        names = self.manifest.group_names
        if grid is not None and not (self.one_pass and one_pass is not False):
            raise ValueError("render_groups: a PinholeGrid needs the one-pass integrator (a JIT variant)")
        if self.one_pass if one_pass is None else one_pass:
            self.set_groups(None)
            groups = self._group_emitters
            if groups is None:
                groups = integrator.group_emitters(self.scene, [self.group(n).emitters for n in names])
                self._group_emitters = groups
            return integrator.render_groups(self.scene, groups, spp=spp, seed=seed,
                                            max_depth=self.manifest.render.max_depth, grid=grid, pixels=pixels)
        images = []
        for name in names:
            self.set_groups({name})
            images.append(self.render(spp=spp, seed=seed))
        self.set_groups(None)
        return np.stack(images)

    def render_aux(self, *, spp: int = 64, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """First-hit albedo and shading normal at the current pose, float32 (H, W, 3) each
        (albedo (H, W, 1) in mono variants): the denoiser's guides (Mitsuba's ``aov`` integrator)."""
        if getattr(self, "_aov", None) is None:
            self._aov = self._mi.load_dict({"type": "aov", "aovs": "albedo:albedo,nn:sh_normal"})
        img = np.array(self._mi.render(self.scene, spp=spp, seed=seed, integrator=self._aov), dtype=np.float32)
        return np.ascontiguousarray(img[..., :-3][..., -3:]), np.ascontiguousarray(img[..., -3:])

    def render(self, *, spp: int | None = None, seed: int | None = None) -> np.ndarray:
        """Render the current pose and groups: float32 (H, W, C) radiance."""
        r = self.manifest.render
        img = self._mi.render(self.scene, spp=spp or r.spp, seed=r.seed if seed is None else seed)
        out = np.array(img, dtype=np.float32)
        return out if out.ndim == 3 else out[..., None]

    def group(self, name: str) -> LightGroup:
        return next(g for g in self.manifest.light_groups if g.name == name)
