"""Fault injection: ``gevsim emulate``, ``study`` and ``dataset`` killed with SIGKILL mid-run, then run again.

Each command runs as a subprocess and is killed (kill -9: no cleanup runs) once
it is provably in the middle of its work; the same command is then run to the
end. Afterwards no temporary file or folder is left anywhere (output folders,
render cache), no process the killed one started is alive, and the finished
outputs equal those of an uninterrupted run in numbers.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import tomli_w

from gevsim.cli import main
from gevsim.experiments.dataset import generate, load_dataset_config
from gevsim.experiments.study import load_study
from gevsim.experiments.study_run import collect, run_study

pytestmark = pytest.mark.slow

DATA = Path(__file__).parent / "data"
#: Attributes that hold timings: left out of the comparison of HDF5 files.
TIMINGS = {"render_noise_json"}


def gevsim(*args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "gevsim.cli", *args], cwd=cwd, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)


def children(pid: int) -> set[int]:
    """Every live process whose parent is ``pid``."""
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out.add(int(stat.parent.name))
    return out


def alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def kill_when(proc: subprocess.Popen, ready, *, timeout_s: float = 240.0) -> set[int]:
    """SIGKILL ``proc`` as soon as ``ready()`` holds; returns the processes it had started then."""
    deadline = time.monotonic() + timeout_s
    while not ready():
        if proc.poll() is not None:
            pytest.fail(f"finished (exit {proc.returncode}) before it could be killed: {proc.stderr.read()}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("never reached the point to kill it at")
        time.sleep(0.02)
    spawned = children(proc.pid)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL
    return spawned


def assert_none_alive(pids: set[int], *, within_s: float = 15.0) -> None:
    deadline = time.monotonic() + within_s
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = {p for p in pids if alive(p)}
    for p in left:
        os.kill(p, signal.SIGKILL)
    assert not left, f"processes {left} outlived the killed run"


def stages(*folders: Path) -> list[str]:
    """Hidden files and folders under ``folders`` (temporaries of atomic writes are ``.NAME.gevsim-XXXXXXXX...``),
    but the lock file and the ownership mark of an output folder."""
    return sorted(str(p) for f in folders for p in f.rglob(".*") if p.name not in (".gevsim.lock", ".gevsim.output"))


def finish(proc: subprocess.Popen) -> None:
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err


def h5_contents(path: Path) -> dict:
    """Every dataset's values and every attribute but timings, by name."""
    out = {}
    with h5py.File(path, "r") as f:
        names = [""]
        f.visit(names.append)
        for name in names:
            obj = f[name] if name else f
            out.update({f"{name}@{k}": np.asarray(v).tolist() for k, v in obj.attrs.items() if k not in TIMINGS})
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]
    return out


def assert_same_h5(a: Path, b: Path) -> None:
    ca, cb = h5_contents(a), h5_contents(b)
    assert ca.keys() == cb.keys()
    for key in ca:
        if isinstance(ca[key], np.ndarray):
            np.testing.assert_array_equal(ca[key], cb[key], err_msg=key)
        else:
            assert ca[key] == cb[key], key


def without_timings(obj):
    """A JSON record with its wall-clock fields dropped."""
    if isinstance(obj, dict):
        return {k: without_timings(v) for k, v in obj.items() if k not in ("seconds", "render_s")}
    if isinstance(obj, list):
        return [without_timings(v) for v in obj]
    return obj


def test_emulate_killed_while_writing_then_rerun(tmp_path):
    cfg = tmp_path / "run.toml"
    cfg.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nduration_s = 0.06\nstep_s = 1e-5\nseed = 2\n'
                   'frame_rate_hz = 500.0\n[render]\nwidth = 24\nheight = 18\nspp = 2\n')
    assert main(["emulate", str(cfg), "--out", str(tmp_path / "ref.h5"), "--cache", str(tmp_path / "c0"), "-q"]) == 0
    out, cache = tmp_path / "out" / "x.h5", tmp_path / "cache"
    args = ("emulate", str(cfg), "--out", str(out), "--cache", str(cache), "-q")
    kill_when(gevsim(*args, cwd=tmp_path), lambda: bool(stages(out.parent)))  # events are being written
    assert stages(out.parent) and not out.exists()  # a half-written stage, no output
    finish(gevsim(*args, cwd=tmp_path))
    assert stages(out.parent, cache) == []
    assert_same_h5(out, tmp_path / "ref.h5")


def tiny_study(tmp_path: Path) -> Path:
    path = tmp_path / "study.toml"
    path.write_text(f"""
[study]
scene = "{DATA / 'card.toml'}"
sensor = "davis346"
emulators = ["dvs", "gradient"]
flicker_group = "lamp"
duration_s = 0.004
step_s = 5e-5
frame_rate_hz = 1000.0
seed = 5
repeats = 2
methods = ["dct", "direct"]
[study.render]
width = 24
height = 18
spp = 2
[sweep]
waveform = ["sinusoid", "pwm"]
frequency_hz = [1000.0]
""")
    return path


def repeat_records(out: Path) -> dict:
    return {str(p.relative_to(out)): (without_timings(json.loads(p.read_text())), p.with_suffix(".npz").read_bytes())
            for p in sorted((out / "runs").glob("*/r*.json"))}


def test_study_killed_with_busy_workers_then_rerun(tmp_path):
    cfg = tiny_study(tmp_path)
    study = load_study(cfg)
    reference = run_study(study, tmp_path / "ref", cache_dir=tmp_path / "c0")
    out = tmp_path / "out"
    args = ("study", str(cfg), "--out", str(out), "--workers", "2", "-q")
    # Killed once the first repeat is finished and the others are under way in the workers.
    spawned = kill_when(gevsim(*args, cwd=tmp_path), lambda: bool(list(out.glob("runs/*/r*.json"))))
    assert spawned, "the study had started no workers"
    assert len(list(out.glob("runs/*/r*.json"))) < 4 and not (out / "results.json").exists()
    assert_none_alive(spawned)
    finish(gevsim(*args, cwd=tmp_path))
    assert stages(out) == []
    assert repeat_records(out) == repeat_records(tmp_path / "ref")
    assert (out / "results.json").is_file() and (out / "report.md").is_file()
    same = [json.dumps(without_timings(rows), sort_keys=True, default=float)
            for rows in (collect(study, out), reference)]
    assert same[0] == same[1]


def test_dataset_killed_with_busy_workers_then_rerun(tmp_path):
    ds = {"sequences": 4, "seed": 11, "scenes": [str(DATA / "card.toml")], "sensors": ["davis346"],
          "emulators": ["dvs", "gradient"], "duration_s": 0.01, "step_s": 2e-5, "frame_rate_hz": 1000.0,
          "evreal": True, "render": {"width": 24, "height": 18, "spp": 2},
          "randomize": {"waveforms": ["pwm", "sinusoid"], "light_scale": [0.5, 2.0]}}
    cfg = tmp_path / "dataset.toml"
    cfg.write_text(tomli_w.dumps({"dataset": ds}))
    generate(load_dataset_config(cfg), tmp_path / "ref", cache_dir=tmp_path / "c0")
    out, cache = tmp_path / "out", tmp_path / "cache"
    args = ("dataset", str(cfg), "--out", str(out), "--cache", str(cache), "--workers", "2", "-q")
    spawned = kill_when(gevsim(*args, cwd=tmp_path), lambda: bool(list(out.glob("shards/*.json"))))
    assert spawned, "the dataset run had started no workers"
    assert len(list(out.glob("shards/*.json"))) < 4 and not (out / "dataset.json").exists()
    assert_none_alive(spawned)
    finish(gevsim(*args, cwd=tmp_path))
    assert stages(out, cache) == []
    for i in range(4):
        name = f"seq_{i:05d}"
        assert_same_h5(out / "shards" / f"{name}.h5", tmp_path / "ref" / "shards" / f"{name}.h5")
        for f in (tmp_path / "ref" / "evreal" / name).iterdir():
            assert (out / "evreal" / name / f.name).read_bytes() == f.read_bytes(), f.name
    index = {k: without_timings(json.loads((d / "dataset.json").read_text())) for k, d in
             (("out", out), ("ref", tmp_path / "ref"))}
    assert index["out"]["complete"] and index["out"]["sequences"] == index["ref"]["sequences"]
