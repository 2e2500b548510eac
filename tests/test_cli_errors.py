"""The CLI's error handling: gevsim's own errors are one line and exit code 2; anything else is a bug
and keeps its traceback."""

import pytest

from gevsim import cli
from gevsim._validate import FieldError
from gevsim.errors import ConfigError, MissingExtraError


def _failing(exc):
    def command(args):
        raise exc
    return command


@pytest.mark.parametrize("exc", [ConfigError("bad value", source="x.toml", key="a.b"),
                                 MissingExtraError("plots need matplotlib: pip install 'gevsim[plot]'"),
                                 FieldError("illuminance_lux", "illuminance_lux must be <= 1e+06, got 1e+30")])
def test_gevsim_errors_are_one_line(monkeypatch, capsys, exc):
    monkeypatch.setattr(cli, "cmd_info", _failing(exc))
    assert cli.main(["info"]) == 2
    err = capsys.readouterr().err
    assert err == f"gevsim: error: {exc}\n"


@pytest.mark.parametrize("exc", [ValueError("a bug"), TypeError("a bug"), OSError("a bug"), ImportError("a bug")])
def test_anything_else_is_a_traceback(monkeypatch, exc):
    monkeypatch.setattr(cli, "cmd_info", _failing(exc))
    with pytest.raises(type(exc), match="a bug"):
        cli.main(["info"])


def test_a_dead_worker_is_one_line_with_exit_1(monkeypatch, capsys):
    # A pool whose worker was killed (out of memory, a signal) raised BrokenProcessPool through a traceback.
    from concurrent.futures.process import BrokenProcessPool

    monkeypatch.setattr(cli, "cmd_info", _failing(BrokenProcessPool("A process in the pool was terminated")))
    assert cli.main(["info"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("gevsim: error: a worker process died (A process in the pool") and err.count("\n") == 1


def test_running_out_of_memory_is_one_line(monkeypatch, capsys):
    # numpy's _ArrayMemoryError under `ulimit -v` was a traceback (exit 1).
    import numpy as np

    monkeypatch.setattr(cli, "cmd_info", lambda args: np.empty(2**62, np.uint8))
    assert cli.main(["info"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gevsim: error: out of memory (Unable to allocate 4.00 EiB") and err.count("\n") == 1


def test_memory_checks_honour_the_address_space_limit(monkeypatch):
    from gevsim import _resources

    monkeypatch.setattr(_resources, "physical_memory_bytes", lambda: 2**35)
    monkeypatch.setattr(_resources, "address_space_limit_bytes", lambda: 2**30)
    assert _resources.usable_memory() == (2**30, "this process may use (ulimit -v)")
    monkeypatch.setattr(_resources, "address_space_limit_bytes", lambda: None)
    assert _resources.usable_memory() == (2**35, "this machine has")


def test_verbose_shows_the_traceback_of_input_errors_too(monkeypatch):
    monkeypatch.setattr(cli, "cmd_info", _failing(ConfigError("bad value")))
    with pytest.raises(ConfigError):
        cli.main(["-v", "info"])


def test_numeric_flags_are_checked_by_the_parser(capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main(["reconstruct", "f.h5", "--method", "dct", "--out", "o", "--c", "nan"])
    assert exit_.value.code == 2 and "--c: must be a positive number" in capsys.readouterr().err


DATA = __import__("pathlib").Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def frames_file(tmp_path_factory):
    """A small emulation file from frame mode (no rendering)."""
    import numpy as np

    from gevsim.emulation import run_frames

    y, x = np.mgrid[0:18, 0:24]
    frames = np.array([0.3 + 0.2 * np.sin(x / 4.0 + k) * np.cos(y / 5.0) for k in range(4)])
    path = tmp_path_factory.mktemp("frames") / "f.h5"
    run_frames(frames, np.arange(4) / 30.0, path)
    return path


def test_emulate_into_a_folder_fails_before_any_work(tmp_path, capsys):
    (tmp_path / "out.h5").mkdir()
    cfg = tmp_path / "run.toml"
    cfg.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\n[render]\nwidth = 24\nheight = 18\nspp = 2\n')
    assert cli.main(["emulate", str(cfg), "--out", str(tmp_path / "out.h5"), "--cache", str(tmp_path / "c"),
                     "-q"]) == 2
    assert capsys.readouterr().err == f"gevsim: error: --out: {tmp_path / 'out.h5'} is a folder; name an .h5 file\n"
    assert not (tmp_path / "c").exists() and list((tmp_path / "out.h5").iterdir()) == []
    from gevsim.emulation import load_config, run

    with pytest.raises(ConfigError, match="out.h5: is a folder"):
        run(load_config(cfg), tmp_path / "out.h5", cache_dir=tmp_path / "c")
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize("argv, text", [
    (["render", "card", "--out", "o", "--seed", "-1"], "argument --seed: expected a non-negative integer, got '-1'"),
    (["emulate", "--frames", "d", "--out", "o.h5", "--seed", "-1"], "argument --seed: expected a non-negative integer"),
    (["reconstruct", "f.h5", "--method", "dct", "--out", "o", "--c", "-1"], "argument --c: must be a positive number"),
])
def test_negative_seeds_and_scales_are_refused_by_the_parser(capsys, argv, text):
    with pytest.raises(SystemExit) as exit_:
        cli.main(argv)
    assert exit_.value.code == 2 and text in capsys.readouterr().err


def test_the_library_refuses_them_too(frames_file):
    from gevsim.evaluation import reconstruct_file
    from gevsim.render import load, override

    with pytest.raises(ConfigError, match=r"render\.seed: .*-1"):
        override(load(DATA / "card.toml"), seed=-1)
    for c in (-1.0, 0.0, float("inf")):
        with pytest.raises(ConfigError, match="c: the Poisson scale must be a finite number > 0"):
            reconstruct_file(frames_file, "dct", c=c)
    with pytest.raises(ConfigError, match="contrast_ln"):
        reconstruct_file(frames_file, "direct", contrast_ln=-0.2)


@pytest.mark.parametrize("methods", [",", " , ,"])
def test_an_empty_method_list_is_one_line(tmp_path, capsys, frames_file, methods):
    assert cli.main(["reconstruct", str(frames_file), "--method", methods, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gevsim: error: --method: no method named") and err.count("\n") == 1
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("attr", ["width", "height", "t_end_us"])
def test_a_file_missing_a_root_attribute_is_named(tmp_path, capsys, frames_file, attr):
    import shutil

    import h5py

    bad = tmp_path / "bad.h5"
    shutil.copy(frames_file, bad)
    with h5py.File(bad, "a") as f:
        del f.attrs[attr]
    assert cli.main(["reconstruct", str(bad), "--method", "dct", "--out", str(tmp_path / "r")]) == 2
    assert capsys.readouterr().err == (f"gevsim: error: {bad}: root attribute {attr!r} is missing: not a file "
                                       "written by gevsim, or damaged\n")


@pytest.mark.parametrize("argv", [["render", "a" * 300, "--out", "{tmp}/r"],
                                  ["render", "a" * 300 + ".toml", "--out", "{tmp}/r"],
                                  ["emulate", "experiments/office_small.toml", "--out", "{tmp}/" + "b" * 300 + ".h5"]])
def test_a_name_past_the_file_systems_limit_is_one_line(tmp_path, capsys, argv):
    # A scene name of 300 bytes raised "OSError: File name too long" from the manifest's lookup (issue 36).
    assert cli.main([a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gevsim: error: ") and err.count("\n") == 1 and "too long" in err
    assert " characters)" in err and len(err) < 300  # the name is cut, with its length
    assert list(tmp_path.iterdir()) == []
