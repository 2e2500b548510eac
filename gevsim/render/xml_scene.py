"""Users' own Mitsuba 3 XML scenes as scene builders (DESIGN.md: a manifest's ``builder`` may be
a Python file or a Mitsuba XML file).

The XML file provides the shapes, materials, textures and emitters; the manifest still
provides the camera (pose, field of view), film, sampler, integrator depth, light groups
(which emitters, their spectrum and luminance, their waveform) and optics. So the XML's own
``<sensor>`` and ``<integrator>`` are ignored, and every emitter must belong to a light
group, named by its ``id`` (an area emitter by the ``id`` of its shape). The manifest's
``options`` become the XML's ``$name`` default parameters.

Every file the XML reads (itself, its ``<include>`` files, and each ``filename`` such as
textures, meshes and spectra) is listed by :func:`xml_inputs`, so the render cache key
changes when any of them does.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from gevsim.errors import ConfigError, one_line

__all__ = ["is_xml", "load_xml_objects", "xml_inputs"]


def is_xml(path: Path) -> bool:
    return Path(path).suffix.lower() == ".xml"


def xml_inputs(path: str | Path, *, _seen: set[Path] | None = None) -> list[Path]:
    """The XML file and every file it reads (includes, recursively, and each ``filename``),
    resolved against the file's folder as Mitsuba does, in a stable order. Names that use a
    ``$parameter`` are skipped (they are set by the manifest's options, which are hashed)."""
    path = Path(path).resolve()
    seen = _seen if _seen is not None else set()
    if path in seen:
        return []
    seen.add(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ConfigError(f"cannot read the Mitsuba XML scene: {exc}", source=str(path)) from None
    out = [path]
    for element in root.iter():
        name = None
        if element.tag == "include":
            name = element.get("filename")
        elif element.tag == "string" and element.get("name") == "filename":
            name = element.get("value")
        if not name or "$" in name:
            continue
        target = (path.parent / name).resolve()
        if element.tag == "include":
            out += xml_inputs(target, _seen=seen)
        elif target not in seen:
            seen.add(target)
            out.append(target)
    return out


def load_xml_objects(mi: Any, path: Path, options: dict) -> dict:
    """Load a Mitsuba XML scene and return its shapes and shape-less emitters by id, as the
    objects a Python builder's ``build(options)`` would describe."""
    try:
        scene = mi.load_file(str(path), **{k: str(v) for k, v in options.items()})
    except Exception as exc:
        raise ConfigError(f"Mitsuba could not load the XML scene: {one_line(exc, last=True)}",
                          source=str(path)) from None
    objects: dict = {}
    for shape in scene.shapes():
        objects[shape.id()] = shape
    for emitter in scene.emitters():
        if emitter.get_shape() is None:
            objects[emitter.id()] = emitter
    return objects


def object_emits(obj: Any) -> bool:
    """Whether a loaded Mitsuba object emits light (an emitter, or a shape with one)."""
    is_emitter = getattr(obj, "is_emitter", None)
    return bool(is_emitter()) if callable(is_emitter) else True
