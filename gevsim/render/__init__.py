"""Rendering: Mitsuba back end, scene manifests, light-group basis images.

The names below are imported on first use (:mod:`gevsim._lazy`): listing the scenes reads their
manifests without importing Mitsuba, numba or colour-science.
"""

from gevsim._lazy import attach

TYPE_CHECKING = False
if TYPE_CHECKING:
    from gevsim.render.backend import VariantChoice, activate, choose_variant, find_libllvm
    from gevsim.render.basis import BasisSet, default_cache_dir, render_basis
    from gevsim.render.manifest import SceneManifest, builtin_scenes, load, override
    from gevsim.render.scene import MitsubaScene

__getattr__, __dir__ = attach(__name__, {
    "VariantChoice": "backend", "activate": "backend", "choose_variant": "backend", "find_libllvm": "backend",
    "BasisSet": "basis", "default_cache_dir": "basis", "render_basis": "basis",
    "SceneManifest": "manifest", "builtin_scenes": "manifest", "load": "manifest", "override": "manifest",
    "MitsubaScene": "scene",
})

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
