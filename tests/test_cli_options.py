"""Command-line options: presets listing, -v after the subcommand, run overrides, frame-mode
emulators and seed, reconstruction method lists, progress bars only on a terminal."""

import logging
from pathlib import Path

import numpy as np
import pytest

from gevsim import cli
from gevsim.io import EventReader
from gevsim.pixel.presets import preset_names

DATA = Path(__file__).parent / "data"


def test_presets_lists_every_preset(capsys):
    assert cli.main(["presets"]) == 0
    out = capsys.readouterr().out
    assert all(f"\n{name} " in out for name in preset_names())


def test_verbose_after_the_subcommand_turns_on_gevsims_loggers_only(monkeypatch):
    seen, run = [], cli.cmd_presets
    monkeypatch.setattr(cli, "cmd_presets", lambda args: seen.append(logging.getLogger("gevsim").level) or run(args))
    monkeypatch.setattr(logging.getLogger("gevsim"), "level", logging.NOTSET)
    assert cli.main(["presets", "-v"]) == 0
    assert seen == [logging.DEBUG]  # during the command
    assert logging.getLogger("gevsim").level == logging.NOTSET  # and back after it, for an in-process caller
    assert logging.getLogger().level > logging.DEBUG  # the libraries' loggers stay quiet


def test_no_progress_bar_when_stderr_is_not_a_terminal(capsys):
    update, close = cli._progress("x", True)  # pytest captures stderr: not a terminal
    update(1, 2)
    close()
    err = capsys.readouterr().err
    assert err == "x: 1/2 poses (50 %), 0 s\n"  # a plain line, no bar's carriage returns


def test_emulate_overrides_size_duration_and_emulators(tmp_path):
    config = tmp_path / "run.toml"
    config.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nsensor = "ideal"\nstep_s = 5e-5\n'
                      'frame_rate_hz = 1000.0\n[render]\nspp = 2\n')
    out = tmp_path / "run.h5"
    assert cli.main(["emulate", str(config), "--out", str(out), "-q", "--width", "20", "--height", "14",
                     "--duration", "0.002", "--emulators", "dvs"]) == 0
    with EventReader(out) as r:
        assert (r.width, r.height, r.t_end_us, r.streams) == (20, 14, 2000, ("events",))
        assert "duration_s = 0.002" in r.attrs["config_toml"]
    assert cli.main(["emulate", str(config), "--out", str(out), "--emulators", "dvs,gradnt"]) == 2


@pytest.fixture
def odd_frames(tmp_path):
    from PIL import Image

    folder = tmp_path / "frames"
    folder.mkdir()
    rng = np.random.default_rng(0)
    base = rng.random((15, 21))
    for k in range(6):
        Image.fromarray((255 * np.clip(base * (0.6 + 0.1 * k), 0, 1)).astype(np.uint8)).save(folder / f"{k:03d}.png")
    return folder


def test_frame_mode_emulators_run_odd_frames_and_the_seed_draws_the_mismatch(odd_frames, tmp_path, capsys):
    def run(name, *extra):
        out = tmp_path / f"{name}.h5"
        assert cli.main(["emulate", "--frames", str(odd_frames), "--fps", "100", "--out", str(out),
                         "--emulators", "dvs,gradient", *extra]) == 0
        with EventReader(out) as r:
            assert r.streams == ("events", "gradient_events")
            return r.read("events")

    a, b, c = (run("a", "--threshold-mismatch", "0.05", "--seed", "1"),
               run("b", "--threshold-mismatch", "0.05", "--seed", "1"),
               run("c", "--threshold-mismatch", "0.05", "--seed", "2"))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    out = tmp_path / "x.h5"
    assert cli.main(["emulate", "--frames", str(odd_frames), "--fps", "100", "--out", str(out), "--seed", "1"]) == 2
    assert "--threshold-mismatch" in capsys.readouterr().err
    # The default emulators include resolution compression, which needs even sizes.
    assert cli.main(["emulate", "--frames", str(odd_frames), "--fps", "100", "--out", str(out)]) == 2
    assert "even height and width" in capsys.readouterr().err


def test_frame_mode_log_linlog_is_recorded_and_config_mode_refuses_it(odd_frames, tmp_path, capsys):
    counts = {}
    for mode in ("offset", "linlog"):
        out = tmp_path / f"{mode}.h5"
        assert cli.main(["emulate", "--frames", str(odd_frames), "--fps", "100", "--out", str(out),
                         "--emulators", "dvs", "--log", mode]) == 0
        with EventReader(out) as r:
            assert r.attrs.get("log_mode", "offset") == mode
            counts[mode] = len(r.read("events"))
    assert counts["linlog"] > counts["offset"]  # the offset compresses every change by DN / (DN + 1)
    config = tmp_path / "c.toml"
    config.write_text('[emulation]\nscene = "office"\n')
    assert cli.main(["emulate", str(config), "--out", str(tmp_path / "x.h5"), "--log", "linlog"]) == 2
    assert "--log" in capsys.readouterr().err


def test_reconstruct_refuses_an_empty_method_list(capsys):
    assert cli.main(["reconstruct", "x.h5", "--method", ",", "--out", "o"]) == 2
    assert "no method" in capsys.readouterr().err


def test_every_command_explains_itself_in_sentences_and_its_examples_parse():
    """--help of every command: a description of whole sentences, every option explained, and examples
    that the parser accepts as written (options spelled as they are today)."""
    import argparse
    import shlex

    from gevsim.cli.help import COMMANDS
    from gevsim.cli.parser import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert set(sub.choices) == set(COMMANDS)
    for name, command in sub.choices.items():
        text, examples = COMMANDS[name]
        assert text.endswith(".") and text[0].isupper() and len(text.split(". ")) >= 1
        help_text = command.format_help()
        assert text.split()[0] in help_text and "examples:" in help_text
        missing = [a.dest for a in command._actions if not a.help and not isinstance(a, argparse._HelpAction)]
        assert not missing, f"gevsim {name}: options without help: {missing}"
        for line in examples:
            words = shlex.split(line)
            assert words[:2] == ["gevsim", name]
            parsed = parser.parse_args(words[1:])
            assert parsed.command == name
