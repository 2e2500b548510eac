"""Requests too large to finish are refused before any work, with the numbers and the key."""

from pathlib import Path

import pytest

from gevsim.cli import main

DATA = Path(__file__).parents[1] / "data"


def emulation(tmp_path, emulation="", render="width = 24\nheight = 18\nspp = 2\n", scene=DATA / "card.toml",
              frame_rate_hz="1000.0"):
    path = tmp_path / "run.toml"
    path.write_text(f'[emulation]\nscene = "{scene}"\nemulators = ["dvs"]\nstep_s = 5e-5\n'
                    f'frame_rate_hz = {frame_rate_hz}\n{emulation}\n[render]\n{render}')
    return path


def refused(tmp_path, capsys, cfg) -> str:
    out = tmp_path / "x.h5"
    assert main(["emulate", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists() and not list((tmp_path / "c").glob("*.exr"))  # nothing rendered, nothing written
    return err


def test_a_huge_render_is_refused_with_its_size(tmp_path, capsys):
    err = refused(tmp_path, capsys, emulation(tmp_path, render="width = 100000\nheight = 100000\n"))
    assert "run.toml: render.width: a 100000x100000 render is 1e+04 Mpx (224 GiB per light group" in err
    assert main(["render", str(DATA / "card.toml"), "--out", str(tmp_path / "r"), "--width", "100000", "--height",
                 "100000", "--cache", str(tmp_path / "c"), "-q"]) == 2
    assert "command line: render.width: a 100000x100000 render" in capsys.readouterr().err


def test_a_pose_spacing_that_needs_billions_of_renders_is_refused(tmp_path, capsys):
    err = refused(tmp_path, capsys, emulation(tmp_path, scene="office_pan", emulation="duration_s = 0.002",
                                              render="width = 24\nheight = 18\nspp = 2\nmax_px_per_pose = 1e-9\n"))
    assert "office_pan.toml: render.max_px_per_pose: max_px_per_pose = 1e-09 splits" in err
    assert "poses, each a render of every light group; at most 100000 are allowed" in err


def test_a_basis_larger_than_memory_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("gevsim._resources.physical_memory_bytes", lambda: 2**21)  # chunks of 1 step fit
    err = refused(tmp_path, capsys, emulation(tmp_path, emulation="chunk_steps = 1",
                                              render="width = 320\nheight = 240\nspp = 2\n"))
    assert "card.toml: render.width: 1 poses x 1 light groups of 320x240 px need about 2.93 MiB of memory; " \
           "this machine has 2 MiB" in err


def test_millions_of_frames_are_refused(tmp_path, capsys):
    err = refused(tmp_path, capsys, emulation(tmp_path, frame_rate_hz="1e6", emulation="duration_s = 2.0"))
    assert "run.toml: emulation.frame_rate_hz: frame_rate_hz = 1e+06 over 2 s makes 2e+06 ground-truth " \
           "frames; at most 1000000 are written" in err
    err = refused(tmp_path, capsys, emulation(tmp_path, frame_rate_hz="1e9"))  # faster than the 1 us clock
    assert "frame_rate_hz must be finite and in [0, 1e+06], got 1000000000.0" in err


def test_frames_that_do_not_fit_on_the_disk_are_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("gevsim._resources.free_disk_bytes", lambda path: 10_000)
    err = refused(tmp_path, capsys, emulation(tmp_path, emulation="duration_s = 0.004"))
    assert "run.toml: emulation.frame_rate_hz: 5 ground-truth frames of 24x18 px (frame_rate_hz = 1000 over " \
           "0.004 s) take up to 42.2 KiB; 9.77 KiB are free where" in err


@pytest.mark.parametrize("width, height", [(7680, 4320), (346, 260), (1280, 720)])
def test_sizes_a_user_asks_for_are_accepted(width, height):
    from gevsim.render import load, override

    manifest = override(load(DATA / "card.toml"), width=width, height=height)
    assert (manifest.render.width, manifest.render.height) == (width, height)
