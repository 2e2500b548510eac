"""Fixtures of the event-file tests."""

from pathlib import Path

import pytest

from gevsim import cli

DATA = Path(__file__).parents[1] / "data"


@pytest.fixture(scope="session")
def good(tmp_path_factory):
    """A small good emulation file (card scene, davis346, DVS and gradient events, 24x18 px, 4 ms), made once;
    tests that corrupt or move it work on a copy."""
    tmp = tmp_path_factory.mktemp("good")
    cfg = tmp / "em.toml"
    cfg.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nsensor = "davis346"\nduration_s = 0.004\n'
                   'step_s = 5e-5\nemulators = ["dvs", "gradient"]\n[render]\nwidth = 24\nheight = 18\nspp = 2\n')
    assert cli.main(["emulate", str(cfg), "--out", str(tmp / "good.h5"), "-q", "--cache", str(tmp / "c")]) == 0
    return tmp / "good.h5"
