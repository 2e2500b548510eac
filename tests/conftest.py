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


TEXTURED_BUILDER = '''"""Test scene: a card textured from a .npy file (opened by numpy) and a backdrop whose bitmap
Mitsuba loads itself (a "filename" in the returned dict)."""
from pathlib import Path

import numpy as np

from gevsim.render import shapes as s

HERE = Path(__file__).parent


def build(options):
    card = np.load(HERE / "card_texture.npy")
    backdrop = {"type": "diffuse", "reflectance": {"type": "bitmap", "filename": str(HERE / "backdrop.exr"),
                                                   "raw": True}}
    return {
        "card": s.rectangle([0.0, 0.0, 0.0], [1.0, 0.75], facing="+z", bsdf=s.diffuse(card)),
        "backdrop": s.rectangle([0.0, 0.0, -1.0], [6.0, 6.0], facing="+z", bsdf=backdrop),
        "lamp": s.rectangle([0.0, 0.0, 4.5], [2.0, 2.0], facing="-z", emitter=s.area_light()),
    }
'''


def textured_scene(folder, *, card=0.5, backdrop=0.3):
    """Write a scene whose builder loads two texture files into ``folder``; returns its manifest path.
    Call again with other values to edit the textures (the manifest and builder stay the same)."""
    from pathlib import Path

    from gevsim.io import write_exr

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    y, x = np.mgrid[0:16, 0:16]
    np.save(folder / "card_texture.npy", np.repeat((card * (0.5 + 0.5 * ((x // 4 + y // 4) % 2)))[..., None], 3,
                                                   axis=2).astype(np.float32))
    write_exr(folder / "backdrop.exr", np.full((8, 8, 3), backdrop, np.float32))
    (folder / "textured.py").write_text(TEXTURED_BUILDER)
    manifest = folder / "textured.toml"
    if not manifest.exists():
        manifest.write_text((Path(__file__).parent / "data" / "card.toml").read_text()
                            .replace('name = "card"', 'name = "textured"').replace("card.py", "textured.py"))
    return manifest
