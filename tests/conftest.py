"""Shared fixtures: Mitsuba variants, small renders (64x48, few spp) and seeded RNGs.

Variant fixtures follow Mitsuba 3's ``src/conftest.py``: ``variant_<name>`` (e.g.
``variant_llvm_ad_rgb``, ``variant_scalar_spectral``) activates exactly that variant and
skips the test, saying why, where this Mitsuba build or machine cannot run it, instead of
quietly testing the scalar fallback. ``variant`` is the fast RGB variant the library would
choose (CUDA, else LLVM); ``variants_rgb`` runs a test once on each RGB backend.

Renders that take seconds are marked ``slow`` (``pytest -m "not slow"`` leaves them out;
``make test`` runs everything).
"""

import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

from gevsim import cli
from gevsim.errors import ConfigError
from gevsim.render import activate, load, override
from gevsim.render.backend import FLAVOURS, ScalarFallbackWarning, VariantChoice, activate_variant

# Property tests draw the same examples on every machine and run (derandomized, no example database): a clean
# clone in CI explores exactly what was run here, so a rare example cannot fail one CI run and not the next.
# A search for new counterexamples is a deliberate run: HYPOTHESIS_PROFILE=explore pytest ...
settings.register_profile("gevsim", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False, max_examples=500)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "gevsim"))

#: The longest modules (seconds each on the 2-core VM with cold numba caches), run first: `make test` hands whole
#: modules to its workers in collection order, and a long one picked up last would leave the other cores idle.
FIRST = ("test_cpu_portability.py", "test_typing.py", "validation/test_sensor_validation.py",
         "test_fault_injection.py", "experiments/test_study.py", "experiments/test_dataset.py")


def pytest_collection_modifyitems(config, items):
    """Move the modules of :data:`FIRST` to the front, in that order; the rest keep theirs."""
    def rank(item) -> int:
        path = item.path.as_posix()
        return next((i for i, name in enumerate(FIRST) if path.endswith("tests/" + name)), len(FIRST))

    items.sort(key=rank)  # stable: tests keep their order within a module and among the rest


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


@pytest.fixture(scope="session")
def good(tmp_path_factory):
    """A small good emulation file (card scene, davis346, DVS and gradient events, 24x18 px, 4 ms), made once;
    tests that corrupt or move it work on a copy."""
    tmp = tmp_path_factory.mktemp("good")
    cfg = tmp / "em.toml"
    card = Path(__file__).parent / "data" / "card.toml"
    cfg.write_text(f'[emulation]\nscene = "{card}"\nsensor = "davis346"\nduration_s = 0.004\n'
                   'step_s = 5e-5\nemulators = ["dvs", "gradient"]\n[render]\nwidth = 24\nheight = 18\nspp = 2\n')
    assert cli.main(["emulate", str(cfg), "--out", str(tmp / "good.h5"), "-q", "--cache", str(tmp / "c")]) == 0
    return tmp / "good.h5"
