"""Array jobs (issue 37, item 6): ``--part I/N`` shares the work out, a merge moves it into the output.

The dataset's parts are checked against a single run, bit for bit, in test_dataset.py; here the parsing, and a
study's parts with a stand-in for its jobs (the jobs themselves are the executors' business: test_study.py
shows they give the same numbers anywhere), including a merge that waits for a part still holding its folder.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gevsim.experiments.study_run as study_run
from gevsim.cli import main
from gevsim.errors import ConfigError
from gevsim.experiments import repeat as repeat_mod
from gevsim.experiments.parts import Part, merge_parts, parse_part, part_folder, parts_root
from gevsim.experiments.repeat import STRIP_FILE, repeat_paths
from gevsim.experiments.study import load_study
from gevsim.io import exclusive

DATA = Path(__file__).parents[1] / "data"


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 50), st.data())
def test_parts_split_the_work_once_and_read_back(count, data):
    index = data.draw(st.integers(0, count - 1))
    assert parse_part(f" {index} / {count} ") == Part(index, count) and str(Part(index, count)) == f"{index}/{count}"
    k = data.draw(st.integers(0, 10_000))
    assert [i for i in range(count) if Part(i, count).takes(k)] == [k % count]  # every item in exactly one part


@pytest.mark.parametrize("text, says", [("3/3", "I must be below N"), ("0/0", "N must be from 1 to"),
                                        ("1/2/3", "expected I/N"), ("-1/2", "expected I/N"), ("", "expected I/N"),
                                        ("0/1000001", "N must be from 1 to 1000000")])
def test_a_wrong_part_names_the_flag(text, says):
    with pytest.raises(ConfigError) as info:
        parse_part(text)
    assert info.value.key == "--part" and says in str(info.value)


def test_parts_lie_beside_the_output(tmp_path):
    assert part_folder(tmp_path / "ds", Part(3, 8)) == tmp_path / "ds.parts" / "3-of-8"
    assert parts_root(f"{tmp_path}/ds/") == tmp_path / "ds.parts"


STUDY = """
[study]
name = "tiny"
scene = "{scene}"
sensor = "ideal"
emulators = ["dvs"]
flicker_group = "lamp"
duration_s = 0.003
step_s = 5e-5
repeats = 2
methods = ["direct"]

[sweep]
waveform = ["dc", "sinusoid"]
"""


def fake_repeat(study, params, repeat, out, *, rid, cache_dir=None, keep_files=False, threads=None):
    """A job's files as execute_repeat lays them out (arrays, repeat 0's strip, a scratch render cache, the
    marker last), their bytes set by the job alone."""
    marker, arrays, _ = repeat_paths(out, rid, repeat)
    arrays.parent.mkdir(parents=True, exist_ok=True)
    with open(arrays, "wb") as fh:
        np.savez(fh, counts=np.arange(4) + repeat)
    if repeat == 0:
        (arrays.parent / STRIP_FILE).write_bytes(f"strip of {rid}".encode())
    (Path(out) / "render-cache").mkdir(exist_ok=True)
    (Path(out) / "render-cache" / f"{rid}.exr").write_bytes(b"basis")
    record = {"repeat": repeat, "rid": rid}
    marker.write_text(json.dumps(record))
    return record


@pytest.fixture
def study(tmp_path, monkeypatch):
    monkeypatch.setattr(repeat_mod, "execute_repeat", fake_repeat)
    monkeypatch.setattr(study_run, "collect", lambda study, out, rids: sorted(
        str(p.relative_to(out)) for p in (Path(out) / "runs").rglob("*") if p.is_file()))
    path = tmp_path / "study.toml"
    path.write_text(STUDY.format(scene=DATA / "card.toml"))
    return load_study(path)


HOLDER = """
import sys, time
from gevsim.io import exclusive
with exclusive(sys.argv[1], what="study", kind="study"):
    print("holding", flush=True)
    time.sleep(float(sys.argv[2]))
"""


def test_study_parts_merge_once_all_are_finished_waiting_for_one_still_holding_its_folder(study, tmp_path):
    out = tmp_path / "out"
    rows, info = study_run.run_study_part(study, out, Part(1, 2))  # jobs 1 and 3 of (dc, sinusoid) x 2 repeats
    assert rows is None and (info["jobs"], info["made"], info["merge"], info["unfinished"]) == (2, 2, "waiting", 2)
    held = part_folder(out, Part(1, 2))
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(held), "1.5"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "holding"
        with exclusive(out, what="study", kind="study"):  # a merge that may not wait leaves the busy part
            assert merge_parts(out, study_run.study_work(study_run.study_jobs(study)[1]))["busy"] == [str(held)]
        rows, info = study_run.run_study_part(study, out, Part(0, 2), wait_s=60)  # the last part waits, merges
    finally:
        holder.kill()
        holder.wait()
    assert (info["jobs"], info["made"], info["merge"]) == (2, 2, "complete")
    rids = [study_run.run_id(study, p) for p in study.runs()]
    assert rows == sorted([f"runs/{rid}/{name}" for rid in rids for name in ("r0.json", "r0.npz", "r1.json", "r1.npz",
                                                                           STRIP_FILE)])
    assert not parts_root(out).exists()  # emptied part folders and their render caches are gone
    assert (out / "runs" / rids[1] / STRIP_FILE).read_bytes() == f"strip of {rids[1]}".encode()
    again, info = study_run.run_study_part(study, out, Part(0, 2))  # OUT holds every job: nothing made
    assert (info["made"], info["merge"]) == (0, "complete") and again == rows


@pytest.mark.parametrize("part", ["2/2", "x"])
def test_a_wrong_study_part_is_one_line_and_exit_2(tmp_path, capsys, part):
    path = tmp_path / "study.toml"
    path.write_text(STUDY.format(scene=DATA / "card.toml"))
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--part", part]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("gevsim: error: --part: ") and not (tmp_path / "out").exists()
