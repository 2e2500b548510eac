"""The CLI's error handling: gevsim's own errors are one line and exit code 2; anything else is a bug
and keeps its traceback."""

import pytest

from gevsim import cli
from gevsim.errors import ConfigError, MissingExtraError


def _failing(exc):
    def command(args):
        raise exc
    return command


@pytest.mark.parametrize("exc", [ConfigError("bad value", source="x.toml", key="a.b"),
                                 MissingExtraError("plots need matplotlib: pip install 'gevsim[plot]'")])
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


def test_verbose_shows_the_traceback_of_input_errors_too(monkeypatch):
    monkeypatch.setattr(cli, "cmd_info", _failing(ConfigError("bad value")))
    with pytest.raises(ConfigError):
        cli.main(["-v", "info"])


def test_numeric_flags_are_checked_by_the_parser(capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main(["reconstruct", "f.h5", "--method", "dct", "--out", "o", "--c", "nan"])
    assert exit_.value.code == 2 and "--c: must be a positive number" in capsys.readouterr().err
