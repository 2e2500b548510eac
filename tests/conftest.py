"""Shared fixtures: small renders (64x48, few spp) and seeded RNGs."""

import warnings

import numpy as np
import pytest

from gevsim.render import activate, load, override
from gevsim.render.backend import ScalarFallbackWarning

SMALL = dict(width=64, height=48, spp=4)


@pytest.fixture(scope="session")
def variant():
    """The variant this machine renders with (scalar fallback allowed, quietly)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScalarFallbackWarning)
        return activate("rgb")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def small(scene, **changes):
    """A built-in scene or manifest path at 64x48 and 4 spp."""
    return override(load(scene), **{**SMALL, **changes})
