"""Rendering: Mitsuba back end, scene manifests, light-group basis images."""

from gevsim.render.backend import VariantChoice, activate, choose_variant, find_libllvm
from gevsim.render.basis import BasisSet, default_cache_dir, render_basis
from gevsim.render.manifest import SceneManifest, builtin_scenes, load, override
from gevsim.render.scene import MitsubaScene

__all__ = [
    "BasisSet",
    "MitsubaScene",
    "SceneManifest",
    "VariantChoice",
    "activate",
    "builtin_scenes",
    "choose_variant",
    "default_cache_dir",
    "find_libllvm",
    "load",
    "override",
    "render_basis",
]
