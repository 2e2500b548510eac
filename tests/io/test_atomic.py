"""The one atomic-output mechanism: files and folders appear whole or not at all; a study or dataset folder
(:func:`gevsim.io.exclusive` with a kind) is written into only while it holds what gevsim wrote (issue 36)."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from gevsim.errors import ConfigError
from gevsim.io import MANIFEST, Staged, atomic_dir, atomic_path, exclusive, remove_stale, sweep_stale
from gevsim.io.mark import MARK, read_mark


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


def test_kind_guards_a_foreign_folder(tmp_path):
    foreign = tmp_path / "photos"
    foreign.mkdir()
    (foreign / "holiday.jpg").write_bytes(b"x")
    (foreign / MANIFEST).write_text("{}")  # a manifest.json alone no longer makes a folder gevsim's
    with pytest.raises(ConfigError, match="holds files gevsim did not write") as err:
        with atomic_dir(foreign, kind="render"):
            pass
    assert "--out" not in str(err.value)
    assert (foreign / "holiday.jpg").exists()
    (tmp_path / "file").write_text("x")
    with pytest.raises(ConfigError, match="not a folder"):
        with atomic_dir(tmp_path / "file", kind="render"):
            pass


def test_staged_commit_and_discard(tmp_path):
    kept, dropped = Staged(tmp_path / "k.h5", suffix=".tmp"), Staged(tmp_path / "d.h5", suffix=".tmp")
    assert kept.path.name.startswith(".k.h5.") and kept.path.suffix == ".tmp"
    kept.path.write_bytes(b"data")
    kept.commit()
    dropped.discard()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.h5"]


KILLED_WRITER = """
import os, signal, sys
import numpy as np
from gevsim.events.types import BRIGHTNESS_DTYPE
from gevsim.io import EventWriter, Staged, atomic_dir
folder = sys.argv[1]
w = EventWriter(folder + "/x.h5", width=4, height=3, config_toml="", seed=0)
w.append("events", np.zeros(5, BRIGHTNESS_DTYPE))
Staged(folder + "/maps.npz")
cm = atomic_dir(folder + "/evreal")
cm.__enter__()
os.kill(os.getpid(), signal.SIGKILL)
"""


def stages(folder):
    return sorted(p.name for p in folder.rglob(".*gevsim-*"))


def backdate(paths, seconds=10.0):
    for p in paths:
        t = p.stat().st_mtime - seconds
        os.utime(p, (t, t))


def test_a_killed_writers_stages_are_removed_by_the_next_write_and_live_ones_kept(tmp_path):
    """kill -9 runs no cleanup: its stages stay, unlocked. The next write of the same target removes them;
    a stage a live writer holds is left alone, however old."""
    proc = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(tmp_path)], capture_output=True, text=True)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    left = stages(tmp_path)
    assert len(left) == 3 and any(n.startswith(".x.h5.gevsim-") and n.endswith(".tmp") for n in left)
    live = Staged(tmp_path / "x.h5")  # a concurrent writer of the same file
    backdate(tmp_path.iterdir())
    with atomic_path(tmp_path / "x.h5") as tmp:
        tmp.write_text("new")
    assert [n for n in stages(tmp_path) if n.startswith(".x.h5.")] == [live.path.name]
    live.discard()
    assert sweep_stale(tmp_path) and stages(tmp_path) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h5"]


def test_sweep_removes_only_unheld_stages_past_the_grace_period(tmp_path):
    sub = tmp_path / "runs" / "abc"
    sub.mkdir(parents=True)
    dead = [sub / ".r0.json.gevsim-abcd1234.json", tmp_path / ".outputs-partial.gevsim-0123abcd.tmp"]
    dead[0].write_text("{")
    dead[1].mkdir()
    (dead[1] / "results.csv").write_text("half")
    young = sub / ".r1.json.gevsim-zzzz9999.json"
    keep = [sub / "r0.json", tmp_path / ".config.settings", tmp_path / ".x.h5.abcdefgh.tmp"]
    for p in keep:
        p.write_text("a user's or a finished file")
    backdate([*dead, *keep])
    young.write_text("{")  # just created: a writer may not have locked it yet
    assert sorted(sweep_stale(tmp_path)) == sorted(dead)
    assert all(p.exists() for p in (*keep, young))


def test_a_swap_killed_half_way_is_undone(tmp_path):
    """commit() of a folder moves the old output aside, then the new one in: killed between the two, the
    next write of that folder puts the old output back before anything else."""
    out = tmp_path / "out"
    old = tmp_path / ".out.gevsim-abcd1234.old"
    (old / "x").mkdir(parents=True)
    (old / "x" / "manifest.json").write_text("{}")
    backdate([old])
    assert remove_stale(out) == [old]
    assert (out / "manifest.json").read_text() == "{}" and not old.exists()


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_outputs_follow_the_umask(tmp_path, umask):
    """mkstemp/mkdtemp make 0600/0700 stages; what is committed has the mode a plain open/mkdir would give."""
    import numpy as np

    from gevsim.events.types import BRIGHTNESS_DTYPE
    from gevsim.io import EventWriter, atomic_write_text

    old = os.umask(umask)
    try:
        atomic_write_text(tmp_path / "a.json", "{}")
        with atomic_dir(tmp_path / "folder") as stage:
            (stage / "inside.txt").write_text("x")
        with EventWriter(tmp_path / "e.h5", width=2, height=2, config_toml="", seed=0) as w:
            w.append("events", np.zeros(1, BRIGHTNESS_DTYPE))
        (tmp_path / "plain.txt").write_text("x")
        (tmp_path / "plain").mkdir()
    finally:
        os.umask(old)
    mode = {p.name: p.stat().st_mode & 0o777 for p in tmp_path.iterdir()}
    assert mode["a.json"] == mode["e.h5"] == mode["plain.txt"] == 0o666 & ~umask
    assert mode["folder"] == mode["plain"] == 0o777 & ~umask
    assert (tmp_path / "folder" / "inside.txt").stat().st_mode & 0o777 == 0o666 & ~umask


def _tree(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _mark(folder: Path) -> dict:
    mark = read_mark(folder)
    assert mark is not None, f"{folder} has no mark"
    return mark


def _study(folder: Path, files: dict[str, str]) -> None:
    with exclusive(folder, what="study", kind="study"):
        for name, text in files.items():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_text(text)


def test_a_study_folder_is_written_into_only_while_it_holds_what_gevsim_wrote(tmp_path):
    """A study is resumed, not replaced, but its report, figures and runs' work folders are overwritten or
    deleted by the next run: a note beside them or an edited report is refused first, never lost."""
    study = tmp_path / "s"
    _study(study, {"report.md": "# report", "runs/0123456789abcdef/r0.json": "{}"})
    mark = _mark(study)
    assert "open" not in mark and set(mark["files"]) == {"report.md", "runs/0123456789abcdef/r0.json"}
    (study / "runs" / "0123456789abcdef" / "r0.json").unlink()  # a file gevsim wrote may go: the run redoes it
    _study(study, {"report.md": "# report 2"})
    (study / "report.md").write_text("# my edits")
    (study / "runs" / "0123456789abcdef" / "r0").mkdir()
    (study / "runs" / "0123456789abcdef" / "r0" / "notes.txt").write_text("mine")
    before = _tree(study)
    for name in ("report.md", "runs/0123456789abcdef/r0"):
        with pytest.raises(ConfigError, match=f"s: {name} (was changed since gevsim wrote it|is a folder gevsim did "
                                              "not write); gevsim writes into a study folder only while"):
            _study(study, {"report.md": "# report 3"})
        (study / "report.md").write_text("# report 2")
    assert _tree(study) == {**before, "report.md": b"# report 2"}


def test_a_killed_studys_work_in_progress_is_resumed_and_nothing_else_is_taken(tmp_path):
    """A run that fails (or is killed) leaves its mark open: what it wrote under runs/ is not recorded, and the
    rerun resumes it; everything else must still be what the last good run recorded."""
    study = tmp_path / "s"
    _study(study, {"report.md": "# report"})
    with pytest.raises(RuntimeError), exclusive(study, what="study", kind="study"):
        (study / "runs" / "0123456789abcdef").mkdir(parents=True)
        (study / "runs" / "0123456789abcdef" / "r0.npz").write_bytes(b"half")
        raise RuntimeError("killed")
    assert _mark(study)["open"] is True and "runs/0123456789abcdef/r0.npz" not in _mark(study)["files"]
    (study / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="notes.txt is a file gevsim did not write"):
        _study(study, {})
    (study / "notes.txt").unlink()
    (study / "runs").rename(tmp_path / "elsewhere")
    (study / "runs").symlink_to(tmp_path / "elsewhere")  # gevsim would write and delete through it
    with pytest.raises(ConfigError, match="runs is a symbolic link gevsim did not write"):
        _study(study, {})
    (study / "runs").unlink()
    (tmp_path / "elsewhere").rename(study / "runs")
    _study(study, {"runs/0123456789abcdef/r0.json": "{}"})  # resumed
    assert "open" not in _mark(study) and "runs/0123456789abcdef/r0.npz" in _mark(study)["files"]
    old = tmp_path / "old"  # a mark from before issue 36 records no files: not trusted
    _study(old, {"report.md": "# report"})
    (old / MARK).write_text(json.dumps({"kind": "study", "gevsim": "0.1.0"}))
    with pytest.raises(ConfigError, match=r"old: its mark .* records no files .* \(first: report.md\)"):
        _study(old, {})
