"""Shared fixtures: Mitsuba variants, small renders (64x48, few spp) and seeded RNGs.

Variant fixtures follow Mitsuba 3's ``src/conftest.py``: ``variant_<name>`` (e.g.
``variant_llvm_ad_rgb``, ``variant_scalar_spectral``) activates exactly that variant and
skips the test, saying why, where this Mitsuba build or machine cannot run it, instead of
quietly testing the scalar fallback. ``variant`` is the fast RGB variant the library would
choose (CUDA, else LLVM); ``variants_rgb`` runs a test once on each RGB backend.

Renders that take seconds are marked ``slow`` (``pytest -m "not slow"`` leaves them out;
``make test`` runs everything).
"""

import warnings

import numpy as np
import pytest

from gevsim.errors import ConfigError
from gevsim.render import activate, load, override
from gevsim.render.backend import FLAVOURS, ScalarFallbackWarning, VariantChoice, activate_variant

SMALL = dict(width=64, height=48, spp=4)
BACKENDS = ("scalar", "llvm_ad", "cuda_ad")


def use_variant(name: str) -> VariantChoice:
    """Activate Mitsuba variant ``name``, or skip the calling test when it cannot run here."""
    try:
        return activate_variant(name)
    except ConfigError as exc:
        pytest.skip(f"Mitsuba variant {name} is not usable here: {exc}")


def _variant_fixture(name: str):
    @pytest.fixture
    def fixture() -> VariantChoice:
        return use_variant(name)

    fixture.__doc__ = f"Mitsuba's {name}, active (the test is skipped where it cannot run)."
    return fixture


for _name in (f"{backend}_{flavour}" for backend in BACKENDS for flavour in FLAVOURS):
    globals()[f"variant_{_name}"] = _variant_fixture(_name)
del _name


@pytest.fixture(params=[f"{backend}_rgb" for backend in BACKENDS])
def variants_rgb(request) -> VariantChoice:
    """Each RGB backend in turn (those this machine cannot run are skipped)."""
    return use_variant(request.param)


def fast_variant() -> VariantChoice:
    """Activate the RGB variant :func:`gevsim.render.activate` chooses (CUDA, else LLVM), or skip the
    calling test where only the scalar fallback is left (``GEVSIM_VARIANT`` still pins any variant)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScalarFallbackWarning)
        choice = activate("rgb")
    if choice.fallback:
        pytest.skip(f"no fast Mitsuba variant: {choice.reason}")
    return use_variant(choice.variant)  # set again: a test before may have switched variants


@pytest.fixture
def variant() -> VariantChoice:
    """The fast RGB variant, active (see :func:`fast_variant`)."""
    return fast_variant()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def small(scene, **changes):
    """A built-in scene or manifest path at 64x48 and 4 spp."""
    return override(load(scene), **{**SMALL, **changes})
