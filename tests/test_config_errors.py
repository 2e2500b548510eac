"""Issue 24 #15, #16, #19: bad config files, manifests, presets, frames and flags end in exit code 2 and
exactly one ``gevsim: error:`` line naming the file, the key and the value, with no traceback. Every check
here happens before rendering (or fakes the render), so the file runs in seconds."""

from __future__ import annotations

import fcntl
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from gevsim import cli
from gevsim.errors import ConfigError

DATA = Path(__file__).parent / "data"
PRESET = Path(__file__).parents[1] / "noise" / "davis346.toml"


def one_error(capsys, argv: list[str]) -> str:
    """Run the CLI; assert exit code 2 and one error line; return that line."""
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("gevsim: error: ") and "Traceback" not in err, err
    return err.strip()


@pytest.fixture
def scene(tmp_path) -> Path:
    """The card test scene at 16x12 px, 1 spp, beside its builder."""
    shutil.copy(DATA / "card.py", tmp_path / "card.py")
    text = (DATA / "card.toml").read_text()
    for old, new in (("width = 32", "width = 16"), ("height = 24", "height = 12"), ("spp = 4", "spp = 1")):
        text = text.replace(old, new)
    path = tmp_path / "card.toml"
    path.write_text(text)
    return path


def emulation(tmp_path, scene, *, extra: str = "", sensor: str = "davis346", name: str = "em.toml") -> Path:
    path = tmp_path / name
    path.write_text(f'[emulation]\nscene = "{scene}"\nsensor = "{sensor}"\nemulators = ["dvs"]\n'
                    f'duration_s = 0.002\nstep_s = 2e-5\n{extra}\n[render]\nwidth = 16\nheight = 12\nspp = 1\n')
    return path


def study(tmp_path, scene, *, extra: str = "", sweep: str = 'waveform = ["pwm"]') -> Path:
    path = tmp_path / "study.toml"
    path.write_text(f'[study]\nscene = "{scene}"\nsensor = "ideal"\nemulators = ["dvs", "gradient"]\n'
                    f'flicker_group = "lamp"\nduration_s = 0.002\n{extra}\n[study.render]\nwidth = 16\n'
                    f'height = 12\nspp = 1\n[sweep]\n{sweep}\n')
    return path


def dataset(tmp_path, scene, *, extra: str = "") -> Path:
    path = tmp_path / "dataset.toml"
    path.write_text(f'[dataset]\nsequences = 1\nscenes = ["{scene}"]\nemulators = ["dvs"]\nduration_s = 0.002\n'
                    f'step_s = 2e-5\n{extra}\n[dataset.render]\nwidth = 16\nheight = 12\nspp = 1\n')
    return path


def run_config(command: str, path: Path, tmp_path: Path) -> list[str]:
    out = tmp_path / ("out.h5" if command == "emulate" else "out")
    return [command, str(path), "--out", str(out), "--cache", str(tmp_path / "cache"), "-q"]


# --- config files that cannot be read as TOML (#16) -------------------------------------------------------------

def _binary(path):
    path.write_bytes(b"\xff\xfe[emulation]\n")


def _folder(path):
    path.mkdir()


def _fifo(path):
    os.mkfifo(path)


def _deep_array(path):
    path.write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")


def _deep_table(path):
    path.write_text("[" + ".".join(["a"] * 100) + "]\n")


UNREADABLE = [(_binary, "not UTF-8 text: byte 0 is 0xff"), (_folder, "is a folder, not a file"),
              (_fifo, "not a regular file"), (_deep_array, "nested more than 32 levels deep"),
              (_deep_table, "nested more than 32 levels deep")]


@pytest.mark.parametrize("command", ["emulate", "study", "dataset"])
@pytest.mark.parametrize("make, text", UNREADABLE, ids=[u[0].__name__[1:] for u in UNREADABLE])
def test_an_unreadable_config_is_one_line_naming_the_file(tmp_path, capsys, command, make, text):
    path = tmp_path / "bad.toml"
    make(path)
    err = one_error(capsys, run_config(command, path, tmp_path))
    assert err.startswith(f"gevsim: error: {path}: ") and text in err
    assert not (tmp_path / "cache").exists()


@pytest.mark.parametrize("command", ["emulate", "study", "dataset"])
def test_an_infinite_frame_rate_is_one_line(tmp_path, capsys, scene, command):
    makers: dict[str, Callable[..., Path]] = {"emulate": emulation, "study": study, "dataset": dataset}
    make = makers[command]
    path = make(tmp_path, scene, extra="frame_rate_hz = inf")
    table = {"emulate": "emulation"}.get(command, command)
    err = one_error(capsys, run_config(command, path, tmp_path))
    assert f"{path}: {table}.frame_rate_hz: frame_rate_hz must be finite and in [0, 1e+06], got inf" in err


# --- scene manifests (#16, #19, #15) -----------------------------------------------------------------------------

KEYFRAME = "keyframes = [{ t_s = 0.0, origin = [0.0, 0.0, 3.5], target = [0.0, 0.0, 0.0] }]"
MANIFESTS = [
    ("builder", ('builder = "card.py"', "builder = 5"), "scene.builder: expected the path of a Python builder",
     "got 5"),
    ("extends", ('builder = "card.py"', 'builder = "card.py"\nextends = 5'), "scene.extends: expected the path",
     "got 5"),
    ("scene", ('[scene]\nname = "card"\nbuilder = "card.py"', "scene = 3"), "scene: expected a table", "got 3"),
    ("keyframes string", (KEYFRAME, 'keyframes = "abc"'), "camera.keyframes: expected a list", "got 'abc'"),
    ("keyframes number", (KEYFRAME, "keyframes = 7"), "camera.keyframes: expected a list", "got 7"),
    ("keyframe number", (KEYFRAME, "keyframes = [1, 2]"), "camera.keyframes[0]: expected a table", "got 1"),
    ("motion number", ("[scene]", "motion = 5\n[scene]"), "motion: expected a list", "got 5"),
    ("motion item", ("[scene]", "motion = [5]\n[scene]"), "motion[0]: expected a [[motion]] table", "got 5"),
    ("motion keyframes", ("[optics]", '[[motion]]\nobject = "card"\nkeyframes = 3\n[optics]'),
     "motion[0].keyframes: expected a list", "got 3"),
    ("up parallel", ("target = [0.0, 0.0, 0.0] }", "target = [0.0, 0.0, 0.0], up = [0.0, 0.0, 2.0] }"),
     "camera.keyframes[0].up: [0.0, 0.0, 2.0] is parallel to the view direction", ""),
    ("up zero", ("target = [0.0, 0.0, 0.0] }", "target = [0.0, 0.0, 0.0], up = [0.0, 0.0, 0.0] }"),
     "camera.keyframes[0].up: must not be the zero vector", ""),
    ("luminance", ("luminance_cd_m2 = 1e5", "luminance_cd_m2 = 1e300"),
     "light_groups.lamp.luminance_cd_m2: 1e+300 is above 1e+10 cd/m^2", ""),
    ("radiance", ('spectrum = "LED-B3"\nluminance_cd_m2 = 1e5', "radiance_w_m2_sr = [1e300, 1.0, 1.0]"),
     "light_groups.lamp.radiance_w_m2_sr: [1e+300, 1.0, 1.0] is above 1.46e+07 W/m^2/sr", ""),
]


@pytest.mark.parametrize("old_new, key_text, value", [m[1:] for m in MANIFESTS], ids=[m[0] for m in MANIFESTS])
def test_a_bad_manifest_is_one_line_naming_file_key_and_value(tmp_path, capsys, scene, old_new, key_text, value):
    old, new = old_new
    text = scene.read_text()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new))
    err = one_error(capsys, ["render", str(bad), "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "c"),
                             "-q"])
    assert f"{bad}: {key_text}" in err and value in err
    assert not (tmp_path / "c").exists() and not (tmp_path / "out").exists()


def test_a_builder_that_rejects_its_options_is_one_line(tmp_path, capsys, scene):
    (tmp_path / "picky.py").write_text("def build(options):\n"
                                       "    raise ValueError(f\"unknown poster {options['poster']!r}\")\n")
    bad = tmp_path / "bad.toml"
    bad.write_text(scene.read_text().replace('builder = "card.py"',
                                             'builder = "picky.py"\noptions = { poster = "nope" }'))
    err = one_error(capsys, ["render", str(bad), "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "c"),
                             "-q"])
    assert (f"{bad}: scene.builder: picky.py: build(options) raised ValueError: unknown poster 'nope' "
            "(options {'poster': 'nope'})") in err


def test_any_builder_bug_is_one_line_and_verbose_shows_its_traceback(tmp_path, scene, capsys):
    # A builder is the user's code: an IndexError or ZeroDivisionError in it was a gevsim traceback.
    (tmp_path / "buggy.py").write_text("def build(options):\n    return [][1] if options else 1 / 0\n")
    bad = tmp_path / "bad.toml"
    bad.write_text(scene.read_text().replace('builder = "card.py"', 'builder = "buggy.py"'))
    argv = ["render", str(bad), "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "c"), "-q"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.toml: scene.builder: buggy.py: build(options) raised ZeroDivisionError" in err
    with pytest.raises(ConfigError) as raised:
        cli.main(["-v", *argv])
    assert isinstance(raised.value.__cause__, ZeroDivisionError)


def test_a_non_finite_render_is_refused_before_it_is_cached(tmp_path, capsys, scene, monkeypatch):
    from gevsim.render import pose_render

    def inf_render(scene_, request, **kw):  # what an emitter too bright for float32 gave: inf pixels
        r = scene_.manifest.render
        return np.full((1, r.height, r.width, 3), np.inf, np.float32), None, None, None

    monkeypatch.setattr(pose_render, "render_pose", inf_render)
    assert cli.main(["render", str(scene), "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "c"), "-q"]) == 2
    lines = capsys.readouterr().err.splitlines()  # the render's own info line, then the error
    assert [line for line in lines if line.startswith("gevsim: error:")] == [lines[-1]]
    assert f"{scene}: light_groups: the render at t = 0 s has 576 non-finite pixel values" in lines[-1]
    assert not list((tmp_path / "c").glob("*.exr")) and not (tmp_path / "out").exists()


def test_mitsubas_include_chain_is_one_line(tmp_path, capsys, scene):
    (tmp_path / "a.xml").write_text('<scene version="3.0.0"><include filename="b.xml"/></scene>')
    (tmp_path / "b.xml").write_text('<scene version="3.0.0"><include filename="a.xml"/></scene>')
    bad = tmp_path / "bad.toml"
    bad.write_text(scene.read_text().replace('builder = "card.py"', 'builder = "a.xml"'))
    err = one_error(capsys, ["render", str(bad), "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "c"),
                             "-q"])
    assert f"{tmp_path / 'a.xml'}: Mitsuba could not load the XML scene:" in err
    assert "Exceeded maximum include recursion depth" in err  # the innermost cause, last of the chain


# --- emulation, study and dataset configs (#19) -----------------------------------------------------------------

def test_emulation_names_are_checked_with_file_and_key(tmp_path, capsys, scene):
    cases = [(f'scene = "{scene}"', "scene = 3", "emulation.scene: expected a built-in scene name or a manifest "
                                                 "path, got 3"),
             (f'scene = "{scene}"', 'scene = "offfice"', "emulation.scene: no scene manifest 'offfice' (did you "
                                                         "mean 'office'?)"),
             ('sensor = "davis346"', 'sensor = "davis347"', "emulation.sensor: unknown sensor preset 'davis347' "
                                                            "(did you mean 'davis346'?)")]
    for old, new, text in cases:
        path = emulation(tmp_path, scene)
        path.write_text(path.read_text().replace(old, new))
        assert f"{path}: {text}" in one_error(capsys, run_config("emulate", path, tmp_path))


@pytest.mark.parametrize("extra, sweep, text", [
    ('methods = "dct"', 'waveform = ["pwm"]', "study.methods: expected a list, got 'dct'"),
    ("", 'scene = ["nope"]', "sweep.scene: no scene manifest 'nope'"),
])
def test_study_values_are_one_line_naming_the_key(tmp_path, capsys, scene, extra, sweep, text):
    path = study(tmp_path, scene, extra=extra, sweep=sweep)
    assert f"{path}: {text}" in one_error(capsys, run_config("study", path, tmp_path))


def test_study_scene_of_the_wrong_type(tmp_path, capsys, scene):
    path = study(tmp_path, scene)
    path.write_text(path.read_text().replace(f'scene = "{scene}"', "scene = 3"))
    assert f"{path}: study.scene: expected a scene name or manifest path, got 3" in one_error(
        capsys, run_config("study", path, tmp_path))


# --- sensor presets (#15, #16, #19) ------------------------------------------------------------------------------

@pytest.mark.parametrize("line, new, text", [
    ("dark_current_a = ", "dark_current_a = 0.0", "noise.dark_current_a: the dark current is 0 A; it must be > 0"),
    ("dark_current_spread = ", "dark_current_spread = 1000", "noise.dark_current_spread: dark_current_spread = "
                                                             "1000 is above 3"),
    ("bandwidth_reference_spectrum = ", "bandwidth_reference_spectrum = 65",
     "sensor.bandwidth_reference_spectrum: expected a lamp spectrum name such as 'D65', got 65"),
])
def test_a_bad_preset_is_refused_before_the_render(tmp_path, capsys, scene, line, new, text):
    lines = [new if row.startswith(line) else row for row in PRESET.read_text().splitlines()]
    preset = tmp_path / "preset.toml"
    preset.write_text("\n".join(lines) + "\n")
    path = emulation(tmp_path, scene, sensor=str(preset))
    assert f"{preset}: {text}" in one_error(capsys, run_config("emulate", path, tmp_path))
    assert not (tmp_path / "cache").exists()


def test_sensor_overrides_name_their_table(tmp_path, capsys, scene):
    path = emulation(tmp_path, scene)
    path.write_text(path.read_text() + "[sensor]\ncutoff_hz = -1\n")
    err = one_error(capsys, run_config("emulate", path, tmp_path))
    assert f"{path}: sensor.cutoff_hz: cutoff_hz must be" in err and "got -1" in err


# --- frame mode (#16, #19) ---------------------------------------------------------------------------------------

@pytest.fixture
def frames(tmp_path) -> Path:
    import imageio.v3 as iio

    folder = tmp_path / "frames"
    folder.mkdir()
    for k in range(3):
        iio.imwrite(folder / f"f{k}.png", np.full((12, 16), 40 + 30 * k, np.uint8))
    return folder


@pytest.mark.parametrize("write, flags, text", [
    (lambda f: (f / "timestamps.txt").write_text("-0.5\n0.0\n0.5\n"), [], "timestamps.txt: times must be >= 0 s, "
                                                                          "got -0.5"),
    (lambda f: (f / "timestamps.txt").write_bytes(b"\xff\xfe\x00"), [], "timestamps.txt: not UTF-8 text: byte 0"),
    (lambda f: None, ["--fps", "1e-300"], "frames: fps: frame 2 is at 2e+300 s, past the latest time"),
    # a day and more: the file was written, then refused by every reader (its t_end_us past a day)
    (lambda f: (f / "timestamps.txt").write_text("0\n0.01\n90000\n"), [], "timestamps.txt: frame 2 is at 9e+04 s, "
                                                                           "past the latest time an event file holds"),
    (lambda f: (f / "f3.png").write_text("not an image"), ["--fps", "30"], "f3.png: cannot read the image"),
    # stored in whole microseconds: a second frame on the same tick was a ValueError traceback after loading
    (lambda f: None, ["--fps", "3e6"], "fps: frames 0 and 1 (0.0 s, 3.3333333333333335e-07 s) fall on the same "
                                      "microsecond"),
], ids=["negative time", "binary timestamps", "tiny fps", "over a day", "unreadable image", "same microsecond"])
def test_frame_mode_input_is_one_line(tmp_path, capsys, frames, write, flags, text):
    write(frames)
    err = one_error(capsys, ["emulate", "--frames", str(frames), "--out", str(tmp_path / "o.h5"), *flags])
    assert text in err
    assert not (tmp_path / "o.h5").exists()


# --- command-line flags and runs (#16, #18, #19) -----------------------------------------------------------------

def test_dataset_duration_too_short_is_one_line(tmp_path, capsys, scene):
    path = dataset(tmp_path, scene)
    err = one_error(capsys, run_config("dataset", path, tmp_path) + ["--duration", "1e-9"])
    assert "--duration: duration_s = 1e-09 is shorter than 1 us" in err


def test_a_frame_rate_above_1_mhz_is_one_line(tmp_path, capsys, scene):
    path = dataset(tmp_path, scene)
    path.write_text(path.read_text().replace("[dataset]\n", "[dataset]\nframe_rate_hz = 2e6\n"))
    err = one_error(capsys, run_config("dataset", path, tmp_path))
    assert "frame_rate_hz" in err and "in [0, 1e+06], got 2000000.0" in err


def test_a_duration_longer_than_an_event_file_holds_is_one_line(tmp_path, capsys, scene):
    path = dataset(tmp_path, scene)
    err = one_error(capsys, run_config("dataset", path, tmp_path) + ["--duration", "90000"])
    assert "--duration: duration_s = 90000 is longer than 86400 s (a day)" in err


def test_an_unreachable_dask_scheduler_is_one_line(tmp_path, capsys, scene, monkeypatch):
    from gevsim.experiments import executors

    monkeypatch.setattr(executors, "SCHEDULER_CONNECT_S", 0.5)
    path = study(tmp_path, scene, extra='methods = ["dct"]')
    err = one_error(capsys, run_config("study", path, tmp_path) + ["--executor", "dask", "--scheduler",
                                                                   "tcp://127.0.0.1:1"])
    assert "--scheduler: cannot connect to the Dask scheduler at 'tcp://127.0.0.1:1'" in err


def test_a_refused_lock_names_the_holders_kind(tmp_path, capsys, scene):
    out = tmp_path / "out"
    out.mkdir()
    fd = os.open(out / ".gevsim.lock", os.O_RDWR | os.O_CREAT)
    try:
        os.write(fd, b"4242 study\n")
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # a study holds the folder
        err = one_error(capsys, run_config("dataset", dataset(tmp_path, scene), tmp_path))
        assert f"{out}: another gevsim study is writing into this folder (process 4242)" in err
    finally:
        os.close(fd)


def test_emulate_without_frames_prints_no_nan(tmp_path, capsys, scene):
    path = emulation(tmp_path, scene, extra="frame_rate_hz = 0")
    assert cli.main(run_config("emulate", path, tmp_path)) == 0
    out = capsys.readouterr().out
    assert "nan" not in out and out.splitlines()[1].split()[6] == "-"  # p/frame, after made, delivered, lost


def test_every_loader_shares_one_prelude(tmp_path):
    from gevsim.config import load_table, resolve_relative

    path = tmp_path / "a.toml"
    path.write_text("[one]\nx = 1\n[two]\n")
    raw, reader = load_table(path, what="test config", tables=("one", "two"))
    assert raw == {"one": {"x": 1}, "two": {}} and reader.source == str(path)
    with pytest.raises(ConfigError, match="unknown key 'two'.*allowed: one") as err:
        load_table(path, what="test config", tables=("one",))
    assert err.value.source == str(path)
    with pytest.raises(ConfigError, match="no such test config"):
        load_table(tmp_path / "none.toml", what="test config", tables=())
    assert resolve_relative("sub/p.toml", tmp_path) == str((tmp_path / "sub" / "p.toml").resolve())
    assert resolve_relative("davis346", tmp_path) == "davis346"  # a built-in name
    assert resolve_relative("/abs/p.toml", tmp_path) == "/abs/p.toml" and resolve_relative(3, tmp_path) == 3
