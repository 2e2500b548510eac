"""Issue 24, outputs we own (#4, #5, #6, #14, #20): gevsim replaces or writes into only a folder or file it
wrote, of the same kind; an output is never one of the run's inputs; names from configs cannot leave the
output folder; the lock file is never followed through a link. Issue 36, item 1: ownership by content (the
mark records every file, its size and digest), no recognition of unmarked folders by their layout. Every
refusal is one line, exit 2, and leaves what was there untouched."""

import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest

from gevsim import cli
from gevsim.errors import ConfigError
from gevsim.io import atomic_dir, exclusive
from gevsim.io.atomic import GRACE_S, LOCK_NAME
from gevsim.io.ownership import MARK, check_file, check_folder, check_name, is_event_file, read_mark
from gevsim.render import load

DATA = Path(__file__).parents[1] / "data"


def _tree(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(argv, capsys, *texts):
    capsys.readouterr()  # what earlier commands printed
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


def test_replaced_folders_record_every_file_and_folder(tmp_path):
    out = _render_folder(tmp_path / "r")
    mark = _mark(out)
    assert mark["kind"] == "render" and mark["folders"] == ["basis"]
    assert mark["files"] == {"manifest.json": [2, hashlib.sha256(b"{}").hexdigest()]}
    with atomic_dir(out, kind="render") as stage:  # an earlier render is replaced
        (stage / "frames" / "deep").mkdir(parents=True)
        (stage / "frames" / "deep" / "f.exr").write_bytes(b"12345")
    assert sorted(os.listdir(out)) == [MARK, "frames"]
    assert _mark(out)["folders"] == ["frames", "frames/deep"]
    assert _mark(out)["files"] == {"frames/deep/f.exr": [5, hashlib.sha256(b"12345").hexdigest()]}
    assert sorted(os.listdir(tmp_path)) == ["r"]


def test_a_folder_gevsim_did_not_write_is_refused_and_untouched(tmp_path):
    """#4: a folder that merely held a manifest.json was deleted by render and reconstruct."""
    proj = tmp_path / "proj"
    proj.mkdir()
    (proj / "manifest.json").write_text('{"name": "x"}')
    (proj / "notes.txt").write_text("precious")
    before = _tree(proj)
    for kind in ("render", "reconstruction", "validation", "study", "dataset"):
        with pytest.raises(ConfigError, match=r"proj: holds files gevsim did not write \(manifest.json, notes.txt\) "
                                              r"and no gevsim mark \(\.gevsim\.output\): gevsim replaces or writes "
                                              "into only folders it marked as its own; remove it or choose another"):
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
    with pytest.raises(ConfigError, match="rend: notes.txt is a file gevsim did not write; gevsim replaces a "
                                          "render folder only while it holds what gevsim wrote there"), \
            atomic_dir(rend, kind="render"):
        pass
    assert (rend / "notes.txt").read_text() == "mine"


def test_unmarked_folders_are_never_recognised_by_their_layout(tmp_path):
    """Issue 36: folders without a mark were taken for earlier outputs by their shape (a render's manifest
    keys, a study's runs/, a dataset's shards/, a validation's report.md); none is gevsim's now."""
    layouts = {"render": {"manifest.json": json.dumps({"gevsim": "0.1", "scene": "c", "light_groups": [],
                                                       "poses": []}), "basis/lamp/pose_0000.exr": "x"},
               "study": {"runs/0123456789abcdef/r0.json": "{}", "results.json": "[]", "report.md": "# r"},
               "dataset": {"shards/seq_00000.json": "{}", "dataset.json": "{}"},
               "validation": {"report.md": "# r", "davis346/results.json": "{}"}}
    for kind, files in layouts.items():
        folder = tmp_path / kind
        for name, text in files.items():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_text(text)
        before = _tree(folder)
        with pytest.raises(ConfigError, match=f"{kind}: holds files gevsim did not write .* no gevsim mark"):
            check_folder(folder, kind)
        assert _tree(folder) == before


def test_a_folder_holding_only_gevsim_leftovers_counts_as_empty(tmp_path):
    """The lock file and stages are gevsim's by name: a folder holding only those may be written; a folder
    named like the lock file, or a mark that is not one, is not."""
    out = tmp_path / "o"
    out.mkdir()
    (out / LOCK_NAME).write_text("123 study\n")
    (out / ".r.gevsim-abcd1234.tmp").mkdir()
    check_folder(out, "render")
    (out / LOCK_NAME).unlink()
    (out / LOCK_NAME).mkdir()
    with pytest.raises(ConfigError, match=r"holds files gevsim did not write \(\.gevsim\.lock\)"):
        check_folder(out, "render")
    (out / LOCK_NAME).rmdir()
    (out / MARK).write_text("not json")
    with pytest.raises(ConfigError, match=r"holds files gevsim did not write \(\.gevsim\.output\)"):
        check_folder(out, "render")


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


# Issue 36, "Data loss through ownership": each case is refused with one line, exit 2, and no file is lost.
def _render(out: Path, cache: Path) -> list[str]:
    return ["render", str(DATA / "card.toml"), "--out", str(out), "--width", "16", "--height", "12", "--spp", "1",
            "--cache", str(cache), "-q"]


def test_a_second_render_keeps_what_the_user_put_deep_inside_the_first(tmp_path, capsys):
    """`render --out r` again, after the user put r/basis/notes.txt and r/basis/my_notes/notes.txt into the
    first render: exit 0 and both files deleted (the mark listed only top-level names). A file gevsim wrote and
    the user changed (same name, same size) is the user's now."""
    out, argv = tmp_path / "r", _render(tmp_path / "r", tmp_path / "c")
    assert cli.main(argv) == 0
    (out / "basis" / "my_notes").mkdir()
    (out / "basis" / "my_notes" / "notes.txt").write_text("deep")
    (out / "basis" / "notes.txt").write_text("mine")
    before = _tree(out)
    _refused(argv, capsys, f"{out}: basis/my_notes is a folder gevsim did not write; gevsim replaces a render folder "
                           "only while it holds what gevsim wrote there: move it out or choose another output folder")
    shutil.rmtree(out / "basis" / "my_notes")
    _refused(argv, capsys, "basis/notes.txt is a file gevsim did not write")
    assert _tree(out) == {k: v for k, v in before.items() if "my_notes" not in k}
    (out / "basis" / "notes.txt").unlink()
    exr = next((out / "basis").rglob("*.exr"))
    data = bytearray(exr.read_bytes())
    data[-1] ^= 1  # one bit, same size: only the digest sees it
    exr.write_bytes(bytes(data))
    _refused(argv, capsys, f"basis/lamp/{exr.name} was changed since gevsim wrote it")
    assert exr.read_bytes() == bytes(data)
    exr.unlink()
    _refused(argv, capsys, f"basis/lamp/{exr.name}, which gevsim wrote, is missing (moved or deleted); gevsim "
                           "replaces a render folder only while it holds what gevsim wrote there: restore it, "
                           "remove the folder yourself or choose another output folder")
    shutil.rmtree(out)
    assert cli.main(argv) == 0 and cli.main(argv) == 0  # an untouched render is replaced


def test_a_second_reconstruction_keeps_a_note_in_its_frames(good, tmp_path, capsys):
    out = tmp_path / "rc"
    argv = ["reconstruct", str(good), "--method", "dct", "--out", str(out), "-q"]
    assert cli.main(argv) == 0
    (out / "frames" / "notes.txt").write_text("mine")
    _refused(argv, capsys, f"{out}: frames/notes.txt is a file gevsim did not write; gevsim replaces a "
                           "reconstruction folder")
    assert (out / "frames" / "notes.txt").read_text() == "mine"


def test_validate_and_render_refuse_unmarked_look_alikes(tmp_path, capsys):
    """An old-validation look-alike (report.md, expA/ and expB/ each holding results.json and data.csv) was
    replaced whole by validate; a folder with a render's manifest.json lost basis/data.bin to render."""
    user = tmp_path / "user"
    (user / "report.md").parent.mkdir()
    (user / "report.md").write_text("# my report")
    for exp in ("expA", "expB"):
        (user / exp).mkdir()
        (user / exp / "results.json").write_text("{}")
        (user / exp / "data.csv").write_text("1,2\n")
    before = _tree(user)
    _refused(["validate", "--sensor", "ideal", "--quick", "--out", str(user), "-q"], capsys,
             f"{user}: holds files gevsim did not write (expA, expB, report.md) and no gevsim mark")
    look = tmp_path / "look"
    (look / "basis").mkdir(parents=True)
    (look / "basis" / "data.bin").write_bytes(b"\0" * 64)
    (look / "manifest.json").write_text(json.dumps({"gevsim": "0.1", "scene": "card", "light_groups": ["lamp"],
                                                    "poses": []}))
    look_before = _tree(look)
    _refused(_render(look, tmp_path / "c"), capsys, f"{look}: holds files gevsim did not write (basis, manifest.json)")
    assert _tree(user) == before and _tree(look) == look_before


def test_a_hand_written_mark_is_not_trusted(tmp_path, capsys):
    """`{"kind": "render", "entries": ["notes.txt"]}` beside a user's notes.txt let render delete it."""
    out = tmp_path / "o"
    out.mkdir()
    (out / MARK).write_text(json.dumps({"kind": "render", "entries": ["notes.txt"]}))
    (out / "notes.txt").write_text("precious")
    _refused(_render(out, tmp_path / "c"), capsys, f"{out}: its mark (.gevsim.output) records no files (a mark of an "
                                                   "earlier gevsim, or not gevsim's), so nothing here (first: "
                                                   "notes.txt) can be told from yours")
    forged = {"kind": "render", "folders": [], "files": {"notes.txt": [8, "0" * 64]}}  # right size, wrong digest
    (out / MARK).write_text(json.dumps(forged))
    _refused(_render(out, tmp_path / "c"), capsys, "notes.txt was changed since gevsim wrote it")
    assert (out / "notes.txt").read_text() == "precious"
