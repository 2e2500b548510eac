"""The one atomic-output mechanism: files and folders appear whole or not at all."""

import pytest

from gevsim.errors import ConfigError
from gevsim.io import MANIFEST, Staged, atomic_dir, atomic_path


def test_file_appears_only_on_success(tmp_path):
    target = tmp_path / "sub" / "a.txt"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("killed")
    assert not target.exists() and list((tmp_path / "sub").iterdir()) == []
    with atomic_path(target) as tmp:
        tmp.write_text("whole")
    assert target.read_text() == "whole" and [p.name for p in target.parent.iterdir()] == ["a.txt"]


def test_folder_is_swapped_whole_and_survives_a_failure(tmp_path):
    out = tmp_path / "out"
    with atomic_dir(out) as stage:
        (stage / "one").write_text("1")
    with pytest.raises(RuntimeError):
        with atomic_dir(out) as stage:
            (stage / "two").write_text("2")
            raise RuntimeError("killed")
    assert sorted(p.name for p in out.iterdir()) == ["one"]
    with atomic_dir(out) as stage:
        (stage / "two").write_text("2")
    assert sorted(p.name for p in out.iterdir()) == ["two"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no stage or old copy left


def test_marker_guards_a_foreign_folder(tmp_path):
    foreign = tmp_path / "photos"
    foreign.mkdir()
    (foreign / "holiday.jpg").write_bytes(b"x")
    with pytest.raises(ConfigError, match=f"no gevsim {MANIFEST}") as err:
        with atomic_dir(foreign, marker=MANIFEST):
            pass
    assert "--out" not in str(err.value)
    assert (foreign / "holiday.jpg").exists()
    (tmp_path / "file").write_text("x")
    with pytest.raises(ConfigError, match="not a folder"):
        with atomic_dir(tmp_path / "file", marker=MANIFEST):
            pass


def test_staged_commit_and_discard(tmp_path):
    kept, dropped = Staged(tmp_path / "k.h5", suffix=".tmp"), Staged(tmp_path / "d.h5", suffix=".tmp")
    assert kept.path.name.startswith(".k.h5.") and kept.path.suffix == ".tmp"
    kept.path.write_bytes(b"data")
    kept.commit()
    dropped.discard()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.h5"]
