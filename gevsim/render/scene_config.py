"""What a scene manifest resolves to outside the renderer: its optics and its TOML text
(what every output records)."""

from __future__ import annotations

import tomli_w

from gevsim.optics import Lens, Pixel
from gevsim.optics import from_spec as optics_from_spec
from gevsim.render.manifest import SceneManifest


def scene_optics(manifest: SceneManifest) -> tuple[Lens, Pixel]:
    """(Lens, Pixel) from the manifest's ``[optics]`` table."""
    return optics_from_spec(manifest.optics, source=manifest.source)


def resolved_config(manifest: SceneManifest) -> str:
    """The manifest as resolved (after ``extends`` and command-line overrides), as TOML."""
    return tomli_w.dumps(manifest.raw)
