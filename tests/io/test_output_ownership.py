"""Issue 24, outputs we own (#4, #5, #6, #14, #20): gevsim replaces or writes into only a folder or file it
wrote, of the same kind; an output is never one of the run's inputs; names from configs cannot leave the
output folder; the lock file is never followed through a link. Every refusal is one line, exit 2, and
leaves what was there untouched."""

import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest

from gevsim import cli
from gevsim.errors import ConfigError
from gevsim.io import atomic_dir, exclusive
from gevsim.io.atomic import GRACE_S, LOCK_NAME
from gevsim.io.ownership import MARK, check_file, check_folder, check_name, is_event_file, legacy_kind, read_mark
from gevsim.render import load

DATA = Path(__file__).parents[1] / "data"


def _tree(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(argv, capsys, *texts):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("gevsim: error: ") and "Traceback" not in err, err
    for text in texts:
        assert text in err, err
    return err


def _mark(folder: Path) -> dict:
    mark = read_mark(folder)
    assert mark is not None, f"{folder} has no mark"
    return mark


def _render_folder(path: Path) -> Path:
    with atomic_dir(path, kind="render") as stage:
        (stage / "basis").mkdir()
        (stage / "manifest.json").write_text("{}")
    return path


@pytest.mark.parametrize("name", ["daylight", "street_lamp", "LED-B3", "a.b", "x" * 64])
def test_safe_names_pass(name):
    assert check_name(name, key="k") == name


@pytest.mark.parametrize("name", ["..", ".", "../../escaped", "/tmp/abs", "a/b", "a\\b", "", ".hidden", "-rf",
                                  "x" * 65, "tab\t", 3])
def test_unsafe_names_are_refused_with_the_key(name):
    with pytest.raises(ConfigError, match="f.toml: light_groups: .* is not a safe name"):
        check_name(name, source="f.toml", key="light_groups")


def test_a_light_group_named_as_a_path_is_refused_at_load(tmp_path, capsys):
    """#5: `[light_groups."../../escaped"]` wrote pose_0000.exr outside --out; now the manifest is refused."""
    shutil.copy(DATA / "card.py", tmp_path)
    scene = tmp_path / "trav.toml"
    scene.write_text((DATA / "card.toml").read_text().replace("[light_groups.lamp]", '[light_groups."../../esc"]'))
    with pytest.raises(ConfigError, match="light_groups: '../../esc' is not a safe name"):
        load(scene)
    out = tmp_path / "a" / "b" / "out"
    _refused(["render", str(scene), "--out", str(out), "-q"], capsys, str(scene), "light_groups")
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["card.py", "trav.toml"]


def test_replaced_folders_carry_their_kind_and_entries(tmp_path):
    out = _render_folder(tmp_path / "r")
    mark = _mark(out)
    assert mark["kind"] == "render" and mark["entries"] == ["basis", "manifest.json"]
    with atomic_dir(out, kind="render") as stage:  # an earlier render is replaced
        (stage / "manifest.json").write_text("{}")
    assert sorted(os.listdir(out)) == [MARK, "manifest.json"] and _mark(out)["entries"] == ["manifest.json"]
    assert sorted(os.listdir(tmp_path)) == ["r"]


def test_a_folder_gevsim_did_not_write_is_refused_and_untouched(tmp_path):
    """#4: a folder that merely held a manifest.json was deleted by render and reconstruct."""
    proj = tmp_path / "proj"
    proj.mkdir()
    (proj / "manifest.json").write_text('{"name": "x"}')
    (proj / "notes.txt").write_text("precious")
    before = _tree(proj)
    for kind in ("render", "reconstruction", "validation", "study", "dataset"):
        with pytest.raises(ConfigError, match=r"proj: holds files gevsim did not write \(manifest.json, notes.txt\)"):
            check_folder(proj, kind)
    with pytest.raises(ConfigError, match="holds files gevsim did not write"), atomic_dir(proj, kind="render"):
        pass
    assert _tree(proj) == before and sorted(os.listdir(tmp_path)) == ["proj"]


def test_an_output_of_another_kind_is_refused(tmp_path):
    """#4: reconstruct --out a render folder deleted the basis; study wrote into a render folder and a later
    render deleted the study."""
    rend = _render_folder(tmp_path / "rend")
    before = _tree(rend)
    with pytest.raises(ConfigError, match="rend: holds a gevsim render output, not a reconstruction output"), \
            atomic_dir(rend, kind="reconstruction"):
        pass
    with pytest.raises(ConfigError, match="holds a gevsim render output, not a study output"), \
            exclusive(rend, what="study", kind="study"):
        pass
    assert _tree(rend) == before  # no lock file, no mark added
    study = tmp_path / "study"
    with exclusive(study, what="study", kind="study"):
        (study / "runs").mkdir()
    assert _mark(study)["kind"] == "study"
    for kind in ("render", "dataset"):
        with pytest.raises(ConfigError, match=f"holds a gevsim study output, not a {kind} output"):
            check_folder(study, kind)
    with exclusive(study, what="study", kind="study"):  # a study resumes in its own folder
        pass


def test_a_file_beside_a_marked_output_is_kept(tmp_path):
    rend = _render_folder(tmp_path / "rend")
    (rend / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match=r"holds files gevsim did not write \(notes.txt\) beside its render"), \
            atomic_dir(rend, kind="render"):
        pass
    assert (rend / "notes.txt").read_text() == "mine"


def test_folders_of_earlier_versions_are_recognised_by_their_layout(tmp_path):
    """Folders written before the mark: a render (manifest keys and only render entries), a study (runs of
    run ids) and a dataset (shards) stay replaceable or resumable; a look-alike with other files does not."""
    rend = tmp_path / "rend"
    (rend / "basis" / "lamp").mkdir(parents=True)
    (rend / "manifest.json").write_text(json.dumps({"gevsim": "0.1", "scene": "c", "light_groups": [], "poses": []}))
    study = tmp_path / "study"
    (study / "runs" / "0123456789abcdef").mkdir(parents=True)
    (study / "results.json").write_text("[]")
    data = tmp_path / "data"
    (data / "shards").mkdir(parents=True)
    (data / "shards" / "seq_00000.json").write_text("{}")
    assert [legacy_kind(p) for p in (rend, study, data)] == ["render", "study", "dataset"]
    with atomic_dir(rend, kind="render") as stage:
        (stage / "manifest.json").write_text("{}")
    assert _mark(rend)["kind"] == "render"
    (tmp_path / "ml" / "runs" / "exp1").mkdir(parents=True)  # a project's own runs/ is no study
    (tmp_path / "other" / "basis").mkdir(parents=True)
    (tmp_path / "other" / "manifest.json").write_text(json.dumps({"gevsim": "0.1", "scene": "c"}))
    assert legacy_kind(tmp_path / "ml") is None and legacy_kind(tmp_path / "other") is None


def test_the_lock_file_is_not_followed(tmp_path):
    """#6: a planted OUT/.gevsim.lock -> victim had its target truncated and overwritten with a PID."""
    victim = tmp_path / "victim.txt"
    victim.write_text("important")
    out = tmp_path / "dsout"
    out.mkdir()
    (out / LOCK_NAME).symlink_to(victim)
    with pytest.raises(ConfigError, match=f"dsout: {LOCK_NAME} is a symbolic link"), exclusive(out):
        pass
    (out / LOCK_NAME).unlink()
    os.link(victim, out / LOCK_NAME)  # a hard link would be truncated the same way
    with pytest.raises(ConfigError, match="not a plain file gevsim made"), exclusive(out, what="dataset"):
        pass
    assert victim.read_text() == "important"


def test_render_and_validate_refuse_before_any_work(tmp_path, capsys):
    study = tmp_path / "study"
    with exclusive(study, what="study", kind="study"):
        pass
    before = _tree(study)
    _refused(["render", str(DATA / "card.toml"), "--out", str(study), "--width", "16", "--height", "12",
              "--spp", "1", "-q"], capsys, f"{study}: holds a gevsim study output, not a render output")
    _refused(["validate", "--sensor", "ideal", "--quick", "--out", str(study), "-q"], capsys,
             "holds a gevsim study output, not a validation output")
    assert _tree(study) == before
    preset = tmp_path / "p.toml"
    preset.write_text((DATA.parents[1] / "noise" / "ideal.toml").read_text()
                      .replace('name = "ideal"', 'name = "../x"'))
    _refused(["validate", "--sensor", str(preset), "--quick", "--out", str(tmp_path / "v"), "-q"], capsys,
             "sensor.name: '../x' is not a safe name")
    assert not (tmp_path / "v").exists()
    mine = tmp_path / "mine"  # a folder holding only the preset validate reads: replacing it would delete it
    mine.mkdir()
    (mine / "my.toml").write_text((DATA.parents[1] / "noise" / "ideal.toml").read_text())
    _refused(["validate", "--sensor", str(mine / "my.toml"), "--quick", "--out", str(mine), "-q"], capsys,
             f"{mine}: holds an input of this run")
    assert sorted(os.listdir(mine)) == ["my.toml"]


def test_folders_from_before_the_mark_are_recognised_only_by_their_whole_layout(tmp_path):
    from gevsim.io.ownership import legacy_kind

    def layout(*names):
        folder = Path(tempfile.mkdtemp(dir=tmp_path))
        for name in names:
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_text("x") if not name.endswith("/") else (folder / name).mkdir(exist_ok=True)
        return legacy_kind(folder)

    assert layout("runs/0123456789abcdef/", "report.md", "results.json", "pareto.png") == "study"
    assert layout("shards/seq_00000.h5", "dataset.json", "evreal/") == "dataset"
    assert layout("report.md", "davis346/results.json") == "validation"
    # a project's own folders are not taken for gevsim's (validate or render would replace them whole)
    assert layout("report.md") is None and layout("runs/") is None
    assert layout("runs/0123456789abcdef/", "notes.txt") is None and layout("shards/", "thesis.tex") is None


def test_reconstruct_refuses_a_render_folder_and_the_folder_holding_its_input(good, tmp_path, capsys):
    rend = _render_folder(tmp_path / "rend")
    before = _tree(rend)
    _refused(["reconstruct", str(good), "--method", "dct", "--out", str(rend), "-q"], capsys,
             "holds a gevsim render output, not a reconstruction output")
    assert _tree(rend) == before
    inrec = tmp_path / "inrec"
    inrec.mkdir()
    shutil.copy(good, inrec / "good.h5")
    _refused(["reconstruct", str(inrec / "good.h5"), "--method", "dct", "--out", str(inrec), "-q"], capsys,
             f"{inrec}: holds an input of this run")
    assert sorted(os.listdir(inrec)) == ["good.h5"]


def test_export_refuses_its_input_a_folder_and_a_foreign_file(good, tmp_path, capsys):
    """#14: `export in.h5 --out in.h5` replaced the emulation file with AEDAT4; --out DIR was a traceback."""
    pytest.importorskip("dv_processing")
    src = tmp_path / "in.h5"
    shutil.copy(good, src)
    data = src.read_bytes()
    _refused(["export", str(src), "--format", "aedat4", "--out", str(src)], capsys, "is an input of this run")
    (tmp_path / "xdir").mkdir()
    _refused(["export", str(src), "--format", "aedat4", "--out", str(tmp_path / "xdir")], capsys,
             "xdir: is a folder")
    foreign = tmp_path / "notes.aedat4"
    foreign.write_text("precious")
    _refused(["export", str(src), "--format", "aedat4", "--out", str(foreign)], capsys,
             "notes.aedat4: exists and is not a gevsim AEDAT4 file")
    assert src.read_bytes() == data and foreign.read_text() == "precious"
    out = tmp_path / "x.aedat4"
    for _ in range(2):  # an earlier export is ours to replace
        assert cli.main(["export", str(src), "--format", "aedat4", "--out", str(out)]) == 0
    assert sorted(os.listdir(tmp_path)) == ["in.h5", "notes.aedat4", "x.aedat4", "xdir"]


def test_emulate_replaces_only_an_emulation_file(good, tmp_path, capsys):
    foreign = tmp_path / "notes.h5"
    foreign.write_text("precious")
    _refused(["emulate", str(DATA / "card.toml"), "--out", str(foreign), "-q"], capsys,
             "notes.h5: exists and is not a gevsim emulation file")
    assert foreign.read_text() == "precious"
    assert is_event_file(good) and not is_event_file(foreign)
    check_file(good, "emulation", is_event_file)  # an earlier emulation file may be replaced


def test_a_killed_runs_leftover_is_swept_when_an_output_is_written_beside_it(tmp_path):
    """#20 (outputs): a stage of another target, left by kill -9, no longer stays until that target is
    written again; a stage a live writer holds is kept (gevsim.io.atomic)."""
    left = tmp_path / ".a.h5.gevsim-abcd1234.tmp"
    left.write_bytes(b"half")
    os.utime(left, (left.stat().st_mtime - 10 * GRACE_S,) * 2)
    _render_folder(tmp_path / "r")
    assert sorted(os.listdir(tmp_path)) == ["r"]
