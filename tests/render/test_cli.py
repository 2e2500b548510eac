"""`gevsim render` end to end, and bad input: one clear error, exit code 2, no partial output."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.io import read_exr

DATA = Path(__file__).parents[1] / "data"
SMALL = ["--width", "32", "--height", "24", "--spp", "2", "-q"]


@pytest.fixture
def scene_dir(tmp_path):
    d = tmp_path / "scene"
    d.mkdir()
    shutil.copy(DATA / "panel.py", d / "panel.py")
    shutil.copy(DATA / "panel.toml", d / "panel.toml")
    return d


def edit(scene_dir, old, new, name="bad.toml"):
    text = (scene_dir / "panel.toml").read_text()
    assert old in text
    path = scene_dir / name
    path.write_text(text.replace(old, new))
    return path


def test_render_writes_basis_frames_and_manifest(scene_dir, tmp_path, capsys):
    out, cache = tmp_path / "out", tmp_path / "cache"
    args = ["render", str(scene_dir / "panel.toml"), "--out", str(out), "--frames", "4000", "--cache", str(cache)]
    assert main(args + SMALL) == 0
    info = json.loads((out / "manifest.json").read_text())
    assert info["scene"] == "panel" and info["seed"] == 7 and info["gevsim"]
    assert "[light_groups.panel]" in info["config_toml"]
    assert [g["name"] for g in info["light_groups"]] == ["panel", "lamp"]
    pwm = info["light_groups"][0]
    assert pwm["percent_flicker"] == pytest.approx(100.0) and pwm["flicker_index"] == pytest.approx(0.75, abs=1e-3)
    assert len(info["frames"]["t_s"]) == 40  # 10 ms at 4 kHz
    img, meta = read_exr(out / pwm["files"][0])
    assert img.shape == (24, 32, 3) and img.dtype == np.float32 and meta["group"] == "panel"
    frame, _ = read_exr(out / info["frames"]["files"][1])
    assert frame.shape == (24, 32, 3)
    # PWM at 1 kHz, duty 0.25: frame 0 (t = 0) is in the on phase, frame 2 (0.5 ms) in the off phase.
    lux = info["frames"]["mean_lux"]
    assert lux[0] > 2 * lux[2]
    assert "1 rendered, 0 from cache" in capsys.readouterr().err
    assert main(args + SMALL) == 0
    assert "0 rendered, 1 from cache" in capsys.readouterr().err
    assert not list(tmp_path.glob(".out.*"))


BAD = [
    ("durration_s", ("duration_s = 0.01", "durration_s = 0.01"), ["sequence.durration_s", "did you mean 'duration_s'"]),
    ("no emitter", ('emitters = ["panel"]', 'emitters = ["pannel"]'), ["light_groups.panel.emitters", "'pannel'",
                                                                        "did you mean 'panel'"]),
    ("negative radiance", ("[3.0, 2.0, 1.0]", "[3.0, -2.0, 1.0]"), ["light_groups.lamp.radiance_w_m2_sr", "negative"]),
    ("nan radiance", ("[3.0, 2.0, 1.0]", "[3.0, nan, 1.0]"), ["light_groups.lamp.radiance_w_m2_sr", "finite"]),
    ("zero-mean waveform",
     ('waveform = { type = "dc" }', 'waveform = { type = "table", times_s = [0.0, 1.0], values = [0.0, 0.0] }'),
     ["light_groups.lamp.waveform", "mean"]),
    ("unknown waveform", ('type = "pwm"', 'type = "pwn"'), ["light_groups.panel.waveform", "did you mean 'pwm'"]),
    ("emitter in no group",
     ('[light_groups.lamp]\nemitters = ["lamp"]\nradiance_w_m2_sr = [3.0, 2.0, 1.0]\nwaveform = { type = "dc" }', ""),
     ["'lamp' belongs to no light group"]),
    ("malformed toml", ("[render]", "[render"), ["malformed TOML"]),
    ("unknown table", ("[optics]", "[optic]"), ["optic", "did you mean 'optics'"]),
    ("negative spp", ("spp = 4", "spp = -4"), ["render.spp", "-4"]),
    ("unknown lamp", ('spectrum = "D65"', 'spectrum = "D66"'), ["light_groups.panel.spectrum", "D65"]),
]


@pytest.mark.parametrize("case, change, expect", BAD, ids=[b[0] for b in BAD])
def test_bad_manifest_is_one_clear_error(scene_dir, tmp_path, capsys, case, change, expect):
    bad = edit(scene_dir, *change)
    out = tmp_path / "out"
    assert main(["render", str(bad), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err, err
    for text in expect:
        assert text in err, err
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]


def test_missing_manifest(tmp_path, capsys):
    assert main(["render", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "nope.toml" in capsys.readouterr().err


def test_unknown_builtin_scene_suggests(tmp_path, capsys):
    assert main(["render", "ofice", "--out", str(tmp_path / "o")]) == 2
    assert "did you mean 'office'" in capsys.readouterr().err


def test_failed_run_keeps_earlier_output(scene_dir, tmp_path):
    out = tmp_path / "out"
    cmd = ["render", str(scene_dir / "panel.toml"), "--out", str(out), "--cache", str(tmp_path / "c")] + SMALL
    assert main(cmd) == 0
    before = (out / "manifest.json").read_bytes()
    bad = edit(scene_dir, 'emitters = ["panel"]', 'emitters = ["nothing"]')
    assert main(["render", str(bad), "--out", str(out), "--cache", str(tmp_path / "c")] + SMALL) == 2
    assert (out / "manifest.json").read_bytes() == before


def test_refuses_to_replace_a_foreign_folder(scene_dir, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    cmd = ["render", str(scene_dir / "panel.toml"), "--out", str(out), "--cache", str(tmp_path / "c")] + SMALL
    assert main(cmd) == 2
    assert "holds files gevsim did not write (thesis.tex)" in capsys.readouterr().err
    assert (out / "thesis.tex").read_text() == "precious" and [p.name for p in out.iterdir()] == ["thesis.tex"]


def test_cli_exit_code_without_traceback(tmp_path):
    out = subprocess.run([sys.executable, "-m", "gevsim.cli", "render", str(tmp_path / "x.toml"), "--out",
                          str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "Traceback" not in out.stderr and "x.toml" in out.stderr
