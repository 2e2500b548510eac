"""Users' own Mitsuba 3 XML scenes as scene builders (DESIGN.md: a manifest's ``builder`` may be
a Python file or a Mitsuba XML file).

The XML file provides the shapes, materials, textures and emitters; the manifest still
provides the camera (pose, field of view), film, sampler, integrator depth, light groups
(which emitters, their spectrum and luminance, their waveform) and optics. So the XML's own
``<sensor>`` and ``<integrator>`` are ignored, and every emitter must belong to a light
group, named by its ``id`` (an area emitter by the ``id`` of its shape). The manifest's
``options`` become the XML's ``$name`` default parameters.

Every file the XML reads (itself, its ``<include>`` files, and each ``filename`` such as
textures, meshes and spectra, names set through ``$name`` parameters included) is listed by
:func:`xml_inputs`, so the render cache key changes when any of them does.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from gevsim.errors import ConfigError, one_line
from gevsim.render.input_files import check_input_file

__all__ = ["is_xml", "load_xml_objects", "xml_inputs"]

#: Deepest chain of ``<include>`` files followed; a deeper one is refused (a cycle is followed once).
MAX_INCLUDE_DEPTH = 32


def is_xml(path: Path) -> bool:
    return Path(path).suffix.lower() == ".xml"


def xml_inputs(path: str | Path, options: dict | None = None) -> list[Path]:
    """The XML file and every file it reads (includes, recursively, ``<spectrum filename>`` and each
    ``<string name="filename">``: textures, meshes, spectra), in document order.

    Names are resolved as Mitsuba does: ``$name`` parameters from ``options`` (the manifest's, as
    :func:`load_xml_objects` passes them), then from the XML's ``<default>`` elements; relative names
    against the ``<path>`` folders, the naming file's folder and the scene's folder (each of them that
    holds the file, so a Mitsuba version searching another one is covered too), else the working
    directory. A name of a folder, device or FIFO, or of a file over
    :data:`~gevsim.render.input_files.MAX_INPUT_BYTES`, raises :class:`ConfigError` naming the XML
    file and the element, before anything is opened (issue 24 #3, #12).
    """
    path = Path(path).resolve()
    check_input_file(path, source=str(path))
    params = [(f"${k}", str(v)) for k, v in (options or {}).items()]
    out: dict[Path, None] = {}
    _walk(path, top=path.parent, params=params, search=[], out=out)
    return list(out)


def _substitute(value: str, params: list[tuple[str, str]]) -> str | None:
    """``value`` with its ``$name`` parameters replaced as Mitsuba's parser does (longest name first,
    ``\\$`` escaped); ``None`` where a parameter stays undefined (Mitsuba refuses that scene)."""
    for key, val in sorted(params, key=lambda kv: -len(kv[0])):
        pos = value.find(key)
        while pos != -1:
            if pos > 0 and value[pos - 1] == "\\":
                pos = value.find(key, pos + len(key))
            else:
                value = value[:pos] + val + value[pos + len(key):]
                pos = value.find(key, pos + len(val))
    if re.search(r"(?<!\\)\$", value):
        return None
    return value.replace("\\$", "$")


def _candidates(name: str, folders: list[Path]) -> list[Path]:
    """Where Mitsuba may find ``name``: in each of ``folders`` that holds it, else in the working
    directory; a name found nowhere is listed in the last folder (hashed as missing)."""
    if Path(name).is_absolute():
        return [Path(name)]
    found = [folder / name for folder in dict.fromkeys(folders) if os.path.lexists(folder / name)]
    if not found and os.path.lexists(name):
        found = [Path.cwd() / name]
    return found or [folders[-1] / name]


def _walk(path: Path, *, top: Path, params: list[tuple[str, str]], search: list[Path], out: dict,
          depth: int = 0) -> None:
    """Add ``path`` and the files it names to ``out``, ``<include>`` files in place, recursively."""
    if path in out:
        return
    if depth > MAX_INCLUDE_DEPTH:
        raise ConfigError(f"<include>s nested more than {MAX_INCLUDE_DEPTH} deep", source=str(path))
    out[path] = None
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ConfigError(f"cannot read the Mitsuba XML scene: {exc}", source=str(path)) from None
    for element in root.iter():
        if element.tag == "default":  # the first value wins: the manifest's options, then the first <default>
            name, value = element.get("name"), _substitute(element.get("value", ""), params)
            if name and value is not None and f"${name}" not in dict(params):
                params.append((f"${name}", value))
            continue
        if element.tag == "path":  # a folder searched first from here on
            folder = _substitute(element.get("value", ""), params)
            if folder:
                search.insert(0, _candidates(folder, [path.parent, top])[0])
            continue
        if element.tag in ("include", "spectrum"):
            raw = element.get("filename")
            key = f'<{element.tag} filename="{raw}">'
        elif element.tag == "string" and element.get("name") == "filename":
            raw = element.get("value")
            key = f'<string name="filename" value="{raw}">'
        else:
            continue
        name = _substitute(raw, params) if raw else None
        if not name:
            continue
        targets = [Path(os.path.abspath(t)) for t in _candidates(name, [*search, path.parent, top])]
        for target in targets:
            check_input_file(target, source=str(path), key=key)
        if element.tag == "include":
            _walk(targets[0].resolve(), top=top, params=params, search=search, out=out, depth=depth + 1)
        out.update(dict.fromkeys(t.resolve() for t in targets if t.resolve() not in out))


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
