"""Requests checked before work (issue 24, #11 and #17): each is refused with one line naming the key, the
number and the limit, before any rendering, and leaves nothing behind. Memory and disk are made small by
patching what gevsim._resources reports, so the numbers do not depend on the machine."""

from __future__ import annotations

import errno
from pathlib import Path

import numpy as np
import pytest

from gevsim.cli import main

DATA = Path(__file__).parent / "data"
GIB = 2**30


@pytest.fixture
def one_gib(monkeypatch):
    monkeypatch.setattr("gevsim._resources.physical_memory_bytes", lambda: GIB)


def refused(tmp_path, capsys, argv) -> str:
    """Run ``argv``: exit 2, one line, no render in the cache; return the line."""
    assert main([*argv, "--cache", str(tmp_path / "c"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("gevsim: error: "), err
    assert not list((tmp_path / "c").glob("*.exr"))
    return err


def emulation(tmp_path, emulation: str) -> Path:
    path = tmp_path / "run.toml"
    path.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nemulators = ["dvs"]\nframe_rate_hz = 0.0\n'
                    f'{emulation}\n[render]\nwidth = 24\nheight = 18\nspp = 2\n')
    return path


def test_a_chunk_larger_than_memory_is_refused(tmp_path, capsys, one_gib):
    cfg = emulation(tmp_path, "duration_s = 10.0\nstep_s = 1e-5\nchunk_steps = 1000000")
    err = refused(tmp_path, capsys, ["emulate", str(cfg), "--out", str(tmp_path / "x.h5")])
    assert "run.toml: emulation.chunk_steps: chunks of 1000000 steps x 24x18 px x 1 emulators need about " \
           "4.83 GiB of memory; this machine has 1 GiB: lower chunk_steps" in err
    assert not (tmp_path / "x.h5").exists()


def test_a_run_of_a_trillion_steps_is_refused(tmp_path, capsys, one_gib):
    cfg = emulation(tmp_path, "duration_s = 8e4\nstep_s = 1e-7")  # (longer than a day is refused as such)
    err = refused(tmp_path, capsys, ["emulate", str(cfg), "--out", str(tmp_path / "x.h5")])
    assert "run.toml: emulation.duration_s: 8e+11 steps (duration_s = 80000 over step_s = 1e-07) need about " \
           "5.82 TiB of memory; this machine has 1 GiB" in err


def test_a_coarse_step_is_sized_with_its_noise_sub_steps(tmp_path, capsys, one_gib):
    # A 10 s step is split into ~10^5 sub-steps (the pixel's fastest noise path): 4497280 x 3072 float64 at
    # 64x48 was a MemoryError traceback. Refused once the render says how many (the render happens first).
    cfg = emulation(tmp_path, "duration_s = 100.0\nstep_s = 10.0")
    assert main(["emulate", str(cfg), "--out", str(tmp_path / "x.h5"), "--cache", str(tmp_path / "c"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "run.toml: emulation.step_s: one step split into " in err  # chunks: from memory
    assert "sub-steps each x 24x18 px x 1 emulators need about" in err
    assert "this machine has 1 GiB: a chunk holds at least one step: shorten step_s (fewer sub-steps)" in err
    assert not (tmp_path / "x.h5").exists()


def test_render_frames_are_counted_and_sized_before_rendering(tmp_path, capsys, monkeypatch):
    render = ["render", str(DATA / "card.toml"), "--out", str(tmp_path / "r"), "--width", "24", "--height", "18",
              "--spp", "2"]
    err = refused(tmp_path, capsys, [*render, "--frames", "1e9"])  # card: 4 ms
    assert "command line: --frames: --frames 1e+09 over the scene's 0.004 s: the frame count is 4e+06; at most " \
           "1e+06 are allowed" in err
    monkeypatch.setattr("gevsim._resources.free_disk_bytes", lambda path: 10_000)
    err = refused(tmp_path, capsys, [*render, "--frames", "1e6"])
    assert "--frames: 4000 frames of 24x18 px take up to 19.8 MiB; 9.77 KiB are free where" in err
    assert not (tmp_path / "r").exists()


def test_a_huge_spp_and_huge_dataset_are_refused_at_load(tmp_path):
    from gevsim.errors import ConfigError
    from gevsim.experiments.dataset import load_dataset_config
    from gevsim.render import load, override

    with pytest.raises(ConfigError, match=r"render.spp: spp must be an integer in 1..1048576, got 1000000000000"):
        override(load(DATA / "card.toml"), spp=10**12)
    path = tmp_path / "ds.toml"
    path.write_text('[dataset]\nsequences = 1000000000000\nscenes = ["office"]\n')
    with pytest.raises(ConfigError, match=r"ds.toml: dataset.sequences: sequences must be an integer in "
                                          r"1..1000000, got 1000000000000"):
        load_dataset_config(path)


def study(tmp_path, sweep: str) -> Path:
    path = tmp_path / "study.toml"
    path.write_text(f'[study]\nscene = "{DATA / "card.toml"}"\nsensor = "ideal"\nemulators = ["dvs"]\n'
                    'flicker_group = "lamp"\nduration_s = 0.003\nstep_s = 5e-5\nframe_rate_hz = 1500.0\n'
                    f'methods = ["direct"]\n[study.render]\nwidth = 24\nheight = 18\nspp = 2\n[sweep]\n{sweep}\n')
    return path


@pytest.mark.parametrize("sweep, message", [
    ('waveform = ["pwm"]\nduty = [0.5, 2.0]', "study.toml: sweep.duty: expected fractions in (0, 1], got 2.0"),
    ('waveform = ["sinusoid"]\nmodulation = [2.0]', "sweep.modulation: expected fractions in (0, 1], got 2.0"),
    (f"frequency_hz = {list(range(1, 1001))}\nlight_scale = {list(range(1, 102))}",
     "study.toml: sweep: the number of runs (the product of the sweep axes' lengths) is 101000; at most 10000"),
])
def test_a_study_is_refused_before_its_folder_is_made(tmp_path, capsys, sweep, message):
    err = refused(tmp_path, capsys, ["study", str(study(tmp_path, sweep)), "--out", str(tmp_path / "s")])
    assert message in err and not (tmp_path / "s").exists()


def test_study_duration_is_refused_before_its_folder_is_made(tmp_path, capsys):
    err = refused(tmp_path, capsys, ["study", str(study(tmp_path, 'waveform = ["dc"]')), "--out",
                                     str(tmp_path / "s"), "--duration", "1e-9"])
    assert "gevsim: error: --duration: duration_s = 1e-09 is shorter than 1 us" in err
    assert not (tmp_path / "s").exists()


def test_study_repeats_are_capped_in_the_config_and_on_the_command_line(tmp_path, capsys):
    path = study(tmp_path, 'waveform = ["dc"]')
    err = refused(tmp_path, capsys, ["study", str(path), "--out", str(tmp_path / "s"), "--repeats", "1001"])
    assert "gevsim: error: --repeats: the number of repeats is 1001; at most 1000 are allowed" in err
    path.write_text(path.read_text().replace("[study]\n", "[study]\nrepeats = 1001\n"))
    err = refused(tmp_path, capsys, ["study", str(path), "--out", str(tmp_path / "s")])
    assert "study.toml: study.repeats:" in err and "1001" in err and not (tmp_path / "s").exists()


def frame_folder(tmp_path, n: int, size: tuple[int, int], times: list[float]) -> Path:
    import imageio.v3 as iio

    folder = tmp_path / "frames"
    folder.mkdir()
    for k in range(n):
        iio.imwrite(folder / f"f{k}.png", np.full(size, 10 * k, np.uint8))
    (folder / "timestamps.txt").write_text("\n".join(map(str, times)) + "\n")
    return folder


def test_frame_mode_times_and_sizes_are_refused_before_emulating(tmp_path, capsys, monkeypatch, one_gib):
    folder = frame_folder(tmp_path, 2, (12, 16), [0.0, 8e4])
    err = refused(tmp_path, capsys, ["emulate", "--frames", str(folder), "--out", str(tmp_path / "x.h5")])
    assert "frames: timestamps: frame times up to 80000 s (a millisecond index per stream) need about " \
           "1.79 GiB of memory; this machine has 1 GiB" in err
    monkeypatch.setattr("gevsim._resources.physical_memory_bytes", lambda: 1024)
    err = refused(tmp_path, capsys, ["emulate", "--frames", str(folder), "--out", str(tmp_path / "x.h5")])
    assert "frames: 2 frames of 16x12 px need about 12 KiB of memory; this machine has 1 KiB: use fewer or " \
           "smaller frames" in err


def test_an_unwritable_output_is_refused_before_the_render(tmp_path, capsys, monkeypatch):
    import tempfile

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(tempfile, "TemporaryFile", read_only)
    cfg = emulation(tmp_path, "duration_s = 0.004\nstep_s = 5e-5")
    for argv, out in ((["emulate", str(cfg)], tmp_path / "ro" / "x.h5"),
                      (["render", str(DATA / "card.toml")], tmp_path / "ro" / "r")):
        err = refused(tmp_path, capsys, [*argv, "--out", str(out)])
        assert err == f"gevsim: error: {out}: cannot write here (Read-only file system); choose another output\n"


def test_an_export_larger_than_the_free_space_is_refused_before_writing(tmp_path, capsys, monkeypatch):
    pytest.importorskip("dv_processing")
    from gevsim.events.types import BRIGHTNESS_DTYPE
    from gevsim.io import EventWriter

    events = np.zeros(1000, BRIGHTNESS_DTYPE)
    events["t"] = np.arange(1000)
    with EventWriter(tmp_path / "in.h5", width=16, height=12, config_toml="", seed=0) as w:
        w.append("events", events)
    monkeypatch.setattr("gevsim._resources.free_disk_bytes", lambda path: 50_000)
    out = tmp_path / "x.aedat4"
    assert main(["export", str(tmp_path / "in.h5"), "--format", "aedat4", "--out", str(out)]) == 2
    assert capsys.readouterr().err == f"gevsim: error: {out}: 1000 events in AEDAT4 take up to 79.8 KiB; " \
                                      f"48.8 KiB are free where {out} goes\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.h5"]
