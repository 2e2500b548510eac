"""Choose and activate the Mitsuba 3 variant.

Order of preference: ``cuda_ad_*`` when a GPU is usable, ``llvm_ad_*`` when a
working libLLVM >= 16 is found, else ``scalar_*`` with a warning that says how
to get the fast one. ``GEVSIM_VARIANT`` overrides the choice.

drjit 1.5's LLVM backend crashes with LLVM 14/15 ("Cannot select fminimum"),
so only libLLVM 16..22 are accepted. drjit reads ``DRJIT_LIBLLVM_PATH`` when it
is first imported, so :func:`activate` sets it before importing Mitsuba.
"""

from __future__ import annotations

import logging
import os
import re
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from gevsim.errors import ConfigError

log = logging.getLogger(__name__)

FLAVOURS = ("rgb", "mono", "spectral")
LLVM_MIN, LLVM_MAX = 16, 22
LIBRARY_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib64",
    "/usr/lib",
    "/usr/local/lib",
    "/opt/homebrew/opt/llvm/lib",
    "/usr/local/opt/llvm/lib",
)
FAST_HINT = (
    "install LLVM >= 16 (Debian/Ubuntu: `apt-get install libllvm19`) or set "
    "DRJIT_LIBLLVM_PATH to a libLLVM >= 16; `make demo`/`make test` do this when run as root"
)


class ScalarFallbackWarning(RuntimeWarning):
    """Mitsuba falls back to its slow scalar variant."""


@dataclass(frozen=True)
class VariantChoice:
    """The chosen Mitsuba variant and why."""

    variant: str
    reason: str
    libllvm: str | None = None
    fallback: bool = False


def llvm_version(path: str | os.PathLike) -> int | None:
    """Major LLVM version from a library file name (``libLLVM-19.so``, ``libLLVM.so.19.1``)."""
    name = Path(path).name
    match = re.search(r"libLLVM[-.](?:so\.)?(\d+)", name) or re.search(r"llvm-(\d+)", str(path))
    return int(match.group(1)) if match else None


def find_libllvm(dirs: Iterable[str | os.PathLike] = LIBRARY_DIRS) -> str | None:
    """Return the newest libLLVM with major version in [16, 22] found in ``dirs``."""
    candidates = []
    for directory in list(dirs) + [f"/usr/lib/llvm-{v}/lib" for v in range(LLVM_MIN, LLVM_MAX + 1)]:
        base = Path(directory)
        if not base.is_dir():
            continue
        for path in base.glob("libLLVM*.so*"):
            version = llvm_version(path)
            if version is not None and LLVM_MIN <= version <= LLVM_MAX:
                candidates.append((version, len(path.name), str(path)))
        for path in base.glob("libLLVM*.dylib"):
            version = llvm_version(path)
            if version is not None and LLVM_MIN <= version <= LLVM_MAX:
                candidates.append((version, len(path.name), str(path)))
    if not candidates:
        return None
    candidates.sort(key=lambda c: (-c[0], c[1]))
    return candidates[0][2]


def choose_variant(
    flavour: str = "rgb",
    *,
    env: Mapping[str, str] | None = None,
    available: tuple[str, ...] | list[str],
    cuda_ok: bool,
    libllvm: str | None,
) -> VariantChoice:
    """Decide the variant without touching Mitsuba (pure; see :func:`activate`).

    Parameters
    ----------
    flavour : {'rgb', 'mono', 'spectral'}
    env : mapping holding ``GEVSIM_VARIANT`` and ``DRJIT_LIBLLVM_PATH`` if set.
    available : the variants this Mitsuba build offers (``mitsuba.variants()``).
    cuda_ok : whether drjit can use a CUDA device.
    libllvm : a libLLVM found by :func:`find_libllvm`, or None.
    """
    env = os.environ if env is None else env
    if flavour not in FLAVOURS:
        raise ConfigError(f"unknown flavour {flavour!r}; choose one of {', '.join(FLAVOURS)}", key="flavour")
    forced = env.get("GEVSIM_VARIANT")
    if forced:
        if forced not in available:
            raise ConfigError(
                f"GEVSIM_VARIANT={forced!r} is not a variant of this Mitsuba build; "
                f"available: {', '.join(available)}",
                key="GEVSIM_VARIANT",
            )
        path = env.get("DRJIT_LIBLLVM_PATH") or libllvm if forced.startswith("llvm") else None
        return VariantChoice(forced, "forced by GEVSIM_VARIANT", path)

    cuda = f"cuda_ad_{flavour}"
    if cuda_ok and cuda in available:
        return VariantChoice(cuda, "a CUDA device is usable")

    llvm = f"llvm_ad_{flavour}"
    scalar = f"scalar_{flavour}"
    user_path = env.get("DRJIT_LIBLLVM_PATH")
    why_not = "no libLLVM 16..22 found in the usual library folders"
    if user_path:
        version = llvm_version(user_path)
        if not Path(user_path).exists():
            why_not = f"DRJIT_LIBLLVM_PATH={user_path} does not exist"
        elif version is not None and version < LLVM_MIN:
            why_not = f"DRJIT_LIBLLVM_PATH={user_path} is LLVM {version}; drjit needs >= {LLVM_MIN}"
        elif llvm in available:
            return VariantChoice(llvm, "DRJIT_LIBLLVM_PATH names a usable libLLVM", user_path)
    elif libllvm and llvm in available:
        return VariantChoice(llvm, f"found libLLVM {llvm_version(libllvm)}", libllvm)
    if scalar not in available and "scalar_rgb" in available and flavour == "mono":
        # PyPI's Mitsuba has no scalar_mono: render RGB, whose luminance the pipeline uses anyway.
        return VariantChoice("scalar_rgb", f"scalar fallback: {why_not}; this Mitsuba build has no scalar_mono, "
                                           f"so RGB is rendered and its luminance used; for the fast variant "
                                           f"{FAST_HINT}", None, True)
    if scalar not in available:
        raise ConfigError(f"Mitsuba offers neither {llvm} nor {scalar}; available: {', '.join(available)}")
    return VariantChoice(scalar, f"scalar fallback: {why_not}; for the fast variant {FAST_HINT}", None, True)


_ACTIVE: VariantChoice | None = None


def _point_drjit_at_libllvm() -> str | None:
    """Set ``DRJIT_LIBLLVM_PATH`` to a found libLLVM unless the user set it (drjit reads it when its
    LLVM backend first initialises); returns the path found, or None."""
    libllvm = None if os.environ.get("DRJIT_LIBLLVM_PATH") else find_libllvm()
    if libllvm:
        os.environ["DRJIT_LIBLLVM_PATH"] = libllvm
    return libllvm


def _usable(backend: str) -> bool:
    """Whether drjit can run its ``"llvm"`` or ``"cuda"`` backend on this machine."""
    import drjit as dr

    try:
        return bool(dr.has_backend(dr.JitBackend.LLVM if backend == "llvm" else dr.JitBackend.CUDA))
    except Exception:  # pragma: no cover - depends on the machine
        return False


def activate_variant(variant: str) -> VariantChoice:
    """Set exactly ``variant`` in Mitsuba, with no fallback (tests pin variants this way).

    Raises :class:`ConfigError` saying why when this Mitsuba build lacks it or the machine cannot
    run its backend (no libLLVM 16..22, no CUDA device). Leaves :func:`activate`'s choice alone.
    """
    env_path = os.environ.get("DRJIT_LIBLLVM_PATH")
    libllvm = _point_drjit_at_libllvm() or env_path
    import mitsuba as mi

    if variant not in mi.variants():
        raise ConfigError(f"{variant!r} is not a variant of this Mitsuba build; available: {', '.join(mi.variants())}")
    backend = variant.split("_", 1)[0]
    if backend in ("llvm", "cuda") and not _usable(backend):
        why = f"drjit could not load libLLVM ({libllvm}); {FAST_HINT}" if backend == "llvm" else "no usable CUDA device"
        raise ConfigError(f"cannot run {variant}: {why}")
    mi.set_variant(variant)
    return VariantChoice(variant, "requested", libllvm if backend == "llvm" else None)


def activate(flavour: str = "rgb") -> VariantChoice:
    """Choose a variant (see :func:`choose_variant`), set it in Mitsuba and return it.

    Warns with :class:`ScalarFallbackWarning` when only the scalar variant is usable.
    """
    global _ACTIVE
    if _ACTIVE is not None and _ACTIVE.variant.endswith("_" + flavour):
        import mitsuba as mi

        mi.set_variant(_ACTIVE.variant)
        return _ACTIVE
    env = dict(os.environ)
    libllvm = _point_drjit_at_libllvm()
    import mitsuba as mi

    cuda_ok = "cuda_ad_rgb" in mi.variants() and _usable("cuda")
    choice = choose_variant(
        flavour, env=env, available=tuple(mi.variants()), cuda_ok=cuda_ok, libllvm=libllvm
    )
    if choice.variant.startswith("llvm") and not _usable("llvm"):
        choice = VariantChoice(
            f"scalar_{flavour}",
            f"scalar fallback: drjit could not load libLLVM ({choice.libllvm}); for the fast variant {FAST_HINT}",
            None,
            True,
        )
    mi.set_variant(choice.variant)
    if choice.fallback:
        warnings.warn(f"gevsim renders with {choice.variant}: {choice.reason}", ScalarFallbackWarning, stacklevel=2)
    log.info("Mitsuba variant %s (%s)", choice.variant, choice.reason)
    _ACTIVE = choice
    return choice


def describe() -> dict:
    """Versions, chosen variant, libLLVM and thread count, for ``gevsim info``."""
    import drjit as dr
    import mitsuba as mi

    import gevsim

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScalarFallbackWarning)
        choice = activate("rgb")
    return {
        "gevsim": gevsim.__version__,
        "mitsuba": mi.__version__,
        "drjit": dr.__version__,
        "variant": choice.variant,
        "reason": choice.reason,
        "libllvm": choice.libllvm or os.environ.get("DRJIT_LIBLLVM_PATH") or "none",
        "threads": dr.thread_count(),
        "variants": ", ".join(mi.variants()),
    }
