"""Issue 24, item 1: values read from an event file are untrusted. A crafted axis, p, coordinate or initial
state used to make compiled kernels write outside their arrays (segfaults, heap corruption); now every
reader refuses them with one line naming the file, before any output is written."""

from pathlib import Path

import h5py
import numpy as np
import pytest

from gevsim import cli
from gevsim.errors import ConfigError
from gevsim.events.gradient import decode
from gevsim.events.types import GRADIENT_DTYPE, check_events
from gevsim.io import EventReader

DATA = Path(__file__).parents[1] / "data"


def _crafted(good, tmp_path, dataset, edit):
    path = tmp_path / "crafted.h5"
    path.write_bytes(good.read_bytes())
    with h5py.File(path, "r+") as f:
        v = f[dataset][...]
        f[dataset][...] = edit(v)
    return path


@pytest.mark.parametrize("dataset, edit, text", [
    ("gradient_events/axis", lambda v: np.full_like(v, 120), "axis other than 0 or 1"),
    ("gradient_events/p", lambda v: np.zeros_like(v), "p other than"),
    ("events/x", lambda v: np.where(np.arange(len(v)) < 3, -20000, v), "outside the 24x18 sensor"),
    ("events/y", lambda v: np.where(np.arange(len(v)) < 3, 30000, v), "outside the 24x18 sensor"),
])
def test_crafted_events_are_refused_by_the_reader(good, tmp_path, capsys, dataset, edit, text):
    path = _crafted(good, tmp_path, dataset, edit)
    stream = dataset.split("/")[0]
    with EventReader(path) as r, pytest.raises(ConfigError, match=text):
        r.read(stream)
    method = "dct" if "gradient" in dataset else "direct"
    for argv in (["reconstruct", str(path), "--method", method, "--out", str(tmp_path / "rec"), "-q"],
                 ["export", str(path), "--format", "aedat4", "--out", str(tmp_path / "x.aedat4")]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert text in err and "Traceback" not in err
    assert not (tmp_path / "rec").exists() and not (tmp_path / "x.aedat4").exists()


def test_a_crafted_initial_state_is_refused(good, tmp_path, capsys):
    path = _crafted(good, tmp_path, "initial_state/gradient", lambda v: np.full_like(v, 100))
    assert cli.main(["reconstruct", str(path), "--method", "dct", "--out", str(tmp_path / "rec"), "-q"]) == 2
    assert "ternary state" in capsys.readouterr().err
    with pytest.raises(ValueError, match="-1, 0 or 1"):
        decode(np.zeros(0, GRADIENT_DTYPE), np.full((2, 3, 4), 7, np.int8))


def test_check_events_bounds():
    ev = np.zeros(2, GRADIENT_DTYPE)
    ev["p"], ev["x"], ev["y"] = 1, [0, 3], [0, 2]
    check_events(ev, shape=(3, 4))
    with pytest.raises(ValueError, match="outside the 4x2 sensor"):
        check_events(ev, shape=(2, 4))
