"""Studies end to end on a tiny scene: outputs, counterfactual physics, resume, kill, bad config."""

import csv
import json
import re
from pathlib import Path

import pytest
from conftest import textured_scene

import gevsim.experiments.study as study_mod
from gevsim.cli import main
from gevsim.errors import ConfigError
from gevsim.experiments import repeat as repeat_mod
from gevsim.experiments.executors import make_executor
from gevsim.experiments.study import load_study
from gevsim.experiments.study_run import run_study
from gevsim.view import LABEL_PX, STRIP_ROWS

iio = pytest.importorskip("imageio.v3")

DATA = Path(__file__).parents[1] / "data"


def write_study(tmp_path, sweep='waveform = ["dc", "sinusoid"]\nmodulation = [0.8]\nfrequency_hz = [1000.0]\n',
                sensor="ideal", extra="", scene=DATA / "card.toml"):
    path = tmp_path / "study.toml"
    path.write_text(f"""
[study]
name = "tiny"
scene = "{scene}"
sensor = "{sensor}"
emulators = ["dvs", "gradient", "gradient_rc", "csdvs"]
flicker_group = "lamp"
duration_s = 0.003
step_s = 5e-5
frame_rate_hz = 1500.0
seed = 3
methods = ["dct", "direct"]
{extra}
[study.render]
width = 24
height = 18
spp = 2

[sweep]
{sweep}
[report]
x = "waveform"
""")
    return path


def test_study_outputs_and_counterfactual_physics(tmp_path, capsys):
    cfg = write_study(tmp_path)
    out = tmp_path / "out"
    assert main(["study", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 0
    table = capsys.readouterr().out
    assert "flicker ev/px/s" in table
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [r["waveform"] for r in rows] == ["dc", "sinusoid"]
    data = json.loads((out / "results.json").read_text())
    steady, flicker = data
    # A steady lamp: no flicker-induced events anywhere; ideal pixel: no noise-induced events.
    for e in ("dvs", "gradient", "gradient_rc", "csdvs"):
        assert steady[f"{e}_flicker_per_pixel_s"] == 0 and flicker[f"{e}_noise_per_pixel_s"] == 0
    # One lamp lights the whole card: its flicker is a uniform ln offset, which an ideal
    # (infinitely fast) pixel passes to the DVS but not to gradients.
    assert flicker["dvs_flicker_per_pixel_s"] > 100
    assert flicker["gradient_flicker_per_pixel_s"] == 0 and flicker["gradient_rc_flicker_per_pixel_s"] == 0
    assert flicker["flicker_frequency_hz"] == pytest.approx(1000.0)
    report = (out / "report.md").read_text()
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    assert images and all((out / name).is_file() for name in images)
    assert (out / "config.toml").read_text() == cfg.read_text()
    assert not list(out.glob(".outputs-partial*"))
    # The report shows what the sensors saw: a strip per run over the last flicker period. The steady
    # lamp and the ideal pixel make no events (DVS panel all background); the flicker makes DVS events.
    strips = [name for name in images if name.endswith("/events.png")]
    assert [s.split("/")[1] for s in strips] == [r["id"] for r in data] and "## What the sensors see" in report
    dc, sine = (iio.imread(out / name)[..., :3] for name in strips)
    assert dc.shape == sine.shape and dc.shape[0] % STRIP_ROWS == 0
    rows_px = dc.shape[0] // STRIP_ROWS
    dvs = [img.reshape(STRIP_ROWS, rows_px, -1, 3)[:, LABEL_PX:LABEL_PX + 18, :24] for img in (dc, sine)]
    assert (dvs[0] == 24).all() and (dvs[1] != 24).any(axis=-1).mean() > 0.5


def test_rerun_resumes_without_recomputing(tmp_path, monkeypatch):
    study = load_study(write_study(tmp_path))
    out = tmp_path / "out"
    first = run_study(study, out, cache_dir=tmp_path / "c")
    markers = {p: p.read_bytes() for p in (out / "runs").glob("*/r*.json")}
    assert len(markers) == 2 * study.base["repeats"]

    def fail(*args, **kwargs):
        raise AssertionError("a finished run was recomputed")

    monkeypatch.setattr(repeat_mod, "execute_repeat", fail)
    again = run_study(study, out, cache_dir=tmp_path / "c")
    assert json.dumps(again) == json.dumps(first)
    assert {p: p.read_bytes() for p in (out / "runs").glob("*/r*.json")} == markers


def test_rerun_after_a_scene_edit_computes_again(tmp_path, monkeypatch):
    """The run id covers the scene's files (manifest, builder, textures) and the gevsim version."""
    scene = textured_scene(tmp_path / "scene")
    study = load_study(write_study(tmp_path, sweep='waveform = ["dc"]\n', extra="repeats = 1", scene=scene))
    out, cache = tmp_path / "out", tmp_path / "c"
    first = run_study(study, out, cache_dir=cache)[0]
    scene.write_text(scene.read_text().replace("luminance_cd_m2 = 1e5", "luminance_cd_m2 = 1e3"))  # 100x dimmer
    dimmed = run_study(study, out, cache_dir=cache)[0]
    assert dimmed["id"] != first["id"]
    assert dimmed["chip_lux_median"] == pytest.approx(first["chip_lux_median"] / 100, rel=1e-3)
    textured_scene(tmp_path / "scene", card=0.05, backdrop=0.05)  # darker textures, same manifest and builder
    darker = run_study(study, out, cache_dir=cache)[0]
    assert darker["id"] not in (first["id"], dimmed["id"])
    assert darker["chip_lux_median"] < 0.5 * dimmed["chip_lux_median"]
    monkeypatch.setattr(study_mod, "__version__", "999.0")
    assert study_mod.run_id(study, study.runs()[0]) != darker["id"]


def test_a_killed_run_leaves_nothing_that_looks_finished(tmp_path, monkeypatch):
    study = load_study(write_study(tmp_path))
    out = tmp_path / "out"
    real = repeat_mod.execute_repeat
    calls = []

    def killed_on_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(repeat_mod, "execute_repeat", killed_on_second)
    with pytest.raises(KeyboardInterrupt):
        run_study(study, out, cache_dir=tmp_path / "c")
    assert len(list((out / "runs").glob("*/r*.json"))) == 1 and not (out / "results.csv").exists()
    monkeypatch.setattr(repeat_mod, "execute_repeat", real)
    assert len(run_study(study, out, cache_dir=tmp_path / "c")) == 2


@pytest.mark.parametrize(
    "sweep, extra, text",
    [
        ('frequency_hz = [100.0]\nwavefrom = ["pwm"]\n', "", "did you mean 'waveform'"),
        ('waveform = ["pwn"]\n', "", "did you mean 'pwm'"),
        ('frequency_hz = [-5.0]\n', "", "sweep.frequency_hz"),
        ('waveform = ["pwm"]\n', 'emulators_x = 1\n', "study.emulators_x"),
    ],
)
def test_malformed_study_config_exits_2(tmp_path, capsys, sweep, extra, text):
    cfg = write_study(tmp_path, sweep=sweep, extra=extra)
    assert main(["study", str(cfg), "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert text in err and "Traceback" not in err


@pytest.mark.parametrize("grid, text", [("duration_s = 1e-9\nstep_s = 1e-10", "study.duration_s: duration_s = 1e-09 "
                                                                           "is shorter than 1 us"),
                                        ("duration_s = 0.003\nstep_s = 4e-4", "study.step_s: the duration")])
def test_a_bad_time_grid_fails_before_any_work(tmp_path, capsys, grid, text):
    cfg = write_study(tmp_path)
    cfg.write_text(cfg.read_text().replace("duration_s = 0.003\nstep_s = 5e-5", grid))
    assert main(["study", str(cfg), "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert text in err and str(cfg) in err and not (tmp_path / "o").exists()


@pytest.mark.parametrize("sweep, text", [
    ('sensor = ["davis346", "davis347"]\n', "sweep.sensor: value 2 of 2: unknown sensor preset 'davis347' (did you "
                                           "mean 'davis346'?)"),
    ('sensor = [3]\n', "sweep.sensor: expected sensor preset names or .toml paths, got 3"),
    ('hysteresis_ln = [0.0, "a"]\n', "sweep.hysteresis_ln: expected non-negative numbers, got 'a'"),
    ('thresholds_ln = [[inf]]\n', "sweep.thresholds_ln: expected lists of positive finite numbers"),
    ('hysteresis_ln = [0.0, 0.1]\nthresholds_ln = [[0.2], [0.05, 0.1]]\n',
     "sweep.hysteresis_ln: hysteresis_ln = 0.1 must be below the smallest threshold 0.05 (run 4 of 4: "),
    ('fill_factor = [0.5, 2.0]\n', "sweep.fill_factor: value 2 of 2: expected a number in (0, 1.0], got 2.0"),
    ('cutoff_hz = [100.0, 0.0]\n', "sweep.cutoff_hz: value 2 of 2: "),
])
def test_every_sweep_value_is_checked_before_the_first_run(tmp_path, capsys, monkeypatch, sweep, text):
    def no_work(*args, **kwargs):
        raise AssertionError("a run started")

    monkeypatch.setattr(repeat_mod, "execute_repeat", no_work)
    cfg = write_study(tmp_path, sweep='waveform = ["dc"]\n' + sweep)
    assert main(["study", str(cfg), "--out", str(tmp_path / "o"), "--cache", str(tmp_path / "c"), "-q"]) == 2
    err = capsys.readouterr().err
    assert f"{cfg}: {text}" in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists() and not (tmp_path / "c").exists()


def test_unknown_flicker_group_fails_before_rendering(tmp_path, capsys):
    cfg = write_study(tmp_path)
    cfg.write_text(cfg.read_text().replace('flicker_group = "lamp"', 'flicker_group = "lamps"'))
    assert main(["study", str(cfg), "--out", str(tmp_path / "o"), "-q"]) == 2
    assert "did you mean 'lamp'" in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_sensor_axes_sweep_preset_parameters(tmp_path):
    """Threshold mismatch is a fixed pattern: with it, a uniform flicker (which an ideal pixel
    would pass to no gradient comparator) still makes no gradient events, since gradients of a
    shifted log image do not change whatever the thresholds; the DVS rate changes with it."""
    sweep = ('waveform = ["sinusoid"]\nmodulation = [0.8]\nfrequency_hz = [1000.0]\n'
             'threshold_mismatch_ln = [0.0, 0.05]\n')
    study = load_study(write_study(tmp_path, sweep=sweep))
    rows = run_study(study, tmp_path / "out", cache_dir=tmp_path / "c")
    assert [r["threshold_mismatch_ln"] for r in rows] == [0.0, 0.05]
    assert all(r["gradient_flicker_per_pixel_s"] == 0 for r in rows)
    assert rows[0]["dvs_events_per_s"] != rows[1]["dvs_events_per_s"]


@pytest.mark.parametrize("methods, text", [('["dct", "dirct"]', "did you mean 'direct'"),
                                           ('["direct_rc"]', "unknown reconstruction method 'direct_rc'"),
                                           ('["sor"]', "needs the 'gradient' emulator")])
def test_study_methods_are_checked_before_any_work(tmp_path, capsys, methods, text):
    cfg = write_study(tmp_path)
    body = cfg.read_text().replace('methods = ["dct", "direct"]', f"methods = {methods}")
    if "sor" in methods:
        body = body.replace('emulators = ["dvs", "gradient", "gradient_rc", "csdvs"]', 'emulators = ["dvs"]')
    cfg.write_text(body)
    assert main(["study", str(cfg), "--out", str(tmp_path / "o"), "-q"]) == 2
    assert text in capsys.readouterr().err and not (tmp_path / "o").exists()


PARALLEL_SWEEP = 'waveform = ["sinusoid"]\nmodulation = [0.8]\nfrequency_hz = [1000.0]\n'


def _records(out):
    """Every repeat's record without its timing, and its arrays' bytes."""
    records = {}
    for marker in sorted((out / "runs").glob("*/r*.json")):
        record = json.loads(marker.read_text())
        record.pop("seconds")
        records[str(marker.relative_to(out))] = (record, marker.with_suffix(".npz").read_bytes())
    return records


def _rows(rows):
    return json.dumps([{k: v for k, v in r.items() if k != "seconds"} for r in rows])


@pytest.mark.parametrize("kind", ["local", "dask"])
def test_executors_give_the_serial_results_bit_for_bit(tmp_path, kind):
    if kind == "dask":
        pytest.importorskip("dask.distributed", reason="the dask extra is not installed")
    study = load_study(write_study(tmp_path, sweep=PARALLEL_SWEEP, sensor="davis346", extra="repeats = 2"))
    serial = run_study(study, tmp_path / "serial", cache_dir=tmp_path / "c")
    with make_executor(kind, workers=2) as executor:
        parallel = run_study(study, tmp_path / "parallel", executor=executor)  # renders into parallel/render-cache
    assert _rows(parallel) == _rows(serial)
    assert _records(tmp_path / "parallel") == _records(tmp_path / "serial")
    assert (tmp_path / "parallel" / "render-cache").is_dir()


HOLDER = """
import sys, time
from gevsim.io import exclusive
with exclusive(sys.argv[1], what="study"):
    print("holding", flush=True)
    time.sleep(600)
"""


def test_a_second_study_on_the_same_folder_is_refused_with_one_line(tmp_path, capsys):
    import subprocess
    import sys

    cfg, out = write_study(tmp_path), tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "holding"  # a study is running in another process
        assert main(["study", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{out}: another gevsim study is writing into this folder" in err
        assert f"(process {holder.pid})" in err
        assert sorted(p.name for p in out.iterdir()) == [".gevsim.lock"] and not (tmp_path / "c").exists()
        with pytest.raises(ConfigError, match="another gevsim study"):
            run_study(load_study(cfg), out, cache_dir=tmp_path / "c")
    finally:
        holder.kill()  # kill -9: the lock goes with the process
        holder.wait()
    assert main(["study", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 0


def test_a_preset_edit_changes_the_run_id_and_relative_presets_are_the_study_files(tmp_path, monkeypatch):
    """Issue 24, item 4: the run id covers the preset's contents (not its path), and a study's relative
    sensor path is taken from the study file's folder, whatever the working directory."""
    from gevsim.pixel.presets import preset_path

    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "my.toml").write_text(preset_path("davis346").read_text())
    (tmp_path / "b" / "my.toml").write_text(
        (tmp_path / "b" / "my.toml").read_text().replace("threshold_on_ln = 0.2 ", "threshold_on_ln = 0.3 "))
    monkeypatch.chdir(tmp_path)
    studies = [load_study(write_study(tmp_path / f, sweep='waveform = ["dc"]\n', sensor="my.toml")) for f in "ab"]
    assert studies[0].base["sensor"] == str((tmp_path / "a" / "my.toml").resolve())
    ids = [study_mod.run_id(s, s.runs()[0]) for s in studies]
    assert ids[0] != ids[1]  # same name, different presets
    before = ids[0]
    preset = tmp_path / "a" / "my.toml"
    edited = re.sub(r"^leak_rate_hz = \S+", "leak_rate_hz = 0.5", preset.read_text(), count=1, flags=re.M)
    assert edited != preset.read_text()  # whatever the preset's own value (it is refitted now and then)
    preset.write_text(edited)
    assert study_mod.run_id(studies[0], studies[0].runs()[0]) != before
