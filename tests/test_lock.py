"""requirements.lock: exact versions for the .venv, consistent with pyproject.toml (issue 21)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement

from gevsim import _lock

ROOT = Path(__file__).resolve().parents[1]


def test_the_lock_pins_every_dependency_within_its_range():
    pins = _lock.read_lock(ROOT / _lock.LOCK_NAME)
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    wanted = list(project["dependencies"]) + [r for extra in project["optional-dependencies"].values() for r in extra]
    for text in wanted:
        req = Requirement(text)
        if req.marker is not None and not req.marker.evaluate():
            continue
        name = _lock.normalise(req.name)
        assert name in pins, f"{req.name} (pyproject.toml) is not in {_lock.LOCK_NAME}: run make lock"
        assert req.specifier.contains(pins[name], prereleases=True), \
            f"{_lock.LOCK_NAME} pins {name}=={pins[name]}, outside pyproject.toml's {req.specifier}"


def test_compare_names_differences_and_missing_packages(tmp_path):
    import numpy

    lock = tmp_path / "requirements.lock"
    lock.write_text(f"# comment\nnumpy=={numpy.__version__}\nNumPy==0.0.1\nno_such_package_xyz==1.0\n")
    pins = _lock.read_lock(lock)
    assert pins == {"numpy": "0.0.1", "no-such-package-xyz": "1.0"}  # names normalised, the last line wins
    differ, missing = _lock.compare(pins)
    assert differ == [f"numpy {numpy.__version__} (locked 0.0.1)"] and missing == ["no-such-package-xyz"]


def test_a_malformed_lock_line_is_named(tmp_path):
    lock = tmp_path / "requirements.lock"
    lock.write_text("numpy>=2\n")
    with pytest.raises(ValueError, match=r"requirements.lock:1: expected 'name==version'"):
        _lock.read_lock(lock)


def test_status_says_whether_this_environment_matches():
    line = _lock.status()
    assert line.startswith(("matches requirements.lock", "does NOT match requirements.lock"))
