"""A full disk (issue 24, #9 and #10): one line and exit 2, no temporary file left, earlier outputs kept;
a full render cache degrades to uncached. ENOSPC is simulated (CI may not mount a small file system):
the event writer and OpenEXR raise what they raise on a full disk, and a subprocess runs under
RLIMIT_FSIZE so that HDF5 meets a real failed write."""

from __future__ import annotations

import errno
import os
import re
import subprocess
import sys
import textwrap
import types
from pathlib import Path

import OpenEXR
import pytest

from gevsim.cli import main
from gevsim.errors import clipped

DATA = Path(__file__).parents[1] / "data"
SMALL = ["--width", "24", "--height", "18", "--spp", "2"]


def leftovers(folder: Path) -> list[str]:
    """Stages (``.<name>.gevsim-XXXXXXXX<suffix>``) left under ``folder``."""
    return sorted(p.name for p in folder.rglob("*") if re.search(r"\.gevsim-[A-Za-z0-9_]{8}", p.name))


@pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "darwin", reason="RLIMIT_FSIZE and SIGXFSZ (Linux)")
def test_a_failed_hdf5_write_closes_the_file_without_a_crash(tmp_path):
    # Before: the failed close left HDF5 identifiers half freed and h5py segfaulted collecting them (exit 139).
    script = textwrap.dedent(f"""
        import errno, gc, resource, signal
        import numpy as np
        from gevsim.events.types import BRIGHTNESS_DTYPE
        from gevsim.io import EventWriter
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes past the limit fail with EFBIG instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))
        rng = np.random.default_rng(0)
        ev = np.zeros(200_000, BRIGHTNESS_DTYPE)
        ev["x"], ev["y"] = rng.integers(0, 64, ev.size), rng.integers(0, 48, ev.size)
        ev["t"], ev["p"] = np.sort(rng.integers(0, 10**6, ev.size)), rng.integers(0, 2, ev.size)
        try:
            with EventWriter({str(tmp_path / "x.h5")!r}, width=64, height=48, config_toml="", seed=0) as w:
                for k in range(5):
                    w.append("events", ev[k * 40_000:(k + 1) * 40_000])
        except OSError as exc:
            print("errno", exc.errno)
        gc.collect()
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["errno", str(errno.EFBIG)]
    assert os.listdir(tmp_path) == []  # the staged file is gone


def emulation(tmp_path: Path) -> Path:
    path = tmp_path / "run.toml"
    path.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nemulators = ["dvs"]\nduration_s = 0.004\n'
                    'step_s = 5e-5\nframe_rate_hz = 0.0\n[render]\nwidth = 24\nheight = 18\nspp = 2\n')
    return path


def test_emulate_on_a_full_disk_prints_one_line_and_keeps_the_earlier_file(tmp_path, capsys, monkeypatch):
    out, cfg = tmp_path / "out" / "run.h5", emulation(tmp_path)
    out.parent.mkdir()
    assert main(["emulate", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 0
    before = out.read_bytes()
    capsys.readouterr()

    def full(self, columns, n):  # what h5py raises: errno 28, the staged file's name only in the message
        raise OSError(errno.ENOSPC, f"Can't synchronously write data (file write failed: filename = "
                                    f"'{self_stage(out)}', errno = 28, error message = 'No space left on device')")

    monkeypatch.setattr("gevsim.io.hdf5._Stream._put", full)
    assert main(["emulate", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q", "--seed", "3"]) == 2
    err = capsys.readouterr().err
    assert err == f"gevsim: error: {clipped(str(out))}: no space left on device\n"
    assert out.read_bytes() == before and leftovers(tmp_path) == []


def test_the_writer_refuses_data_before_hdf5_meets_a_full_disk(tmp_path, capsys, monkeypatch):
    # A study's workers filling one disk still crashed h5py now and then (a failed write of HDF5's own caches
    # leaves identifiers half freed): a chunk that would leave less than HEADROOM_BYTES free is refused first.
    from gevsim import _resources

    out, cfg = tmp_path / "run.h5", emulation(tmp_path)
    assert main(["emulate", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 0
    before = out.read_bytes()
    capsys.readouterr()
    puts = []
    monkeypatch.setattr("gevsim.io.hdf5._Stream._put", lambda self, columns, n: puts.append(n))
    monkeypatch.setattr(_resources, "free_disk_bytes", lambda path: _resources.HEADROOM_BYTES + 100)
    assert main(["emulate", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q", "--seed", "3"]) == 2
    assert capsys.readouterr().err == f"gevsim: error: {clipped(str(out))}: no space left on device\n"
    assert puts == [] and out.read_bytes() == before and leftovers(tmp_path) == []


def test_export_stops_before_dv_processing_meets_a_full_disk(good, tmp_path, capsys, monkeypatch):
    # dv-processing aborts the process (C++ FileWriteError, exit 134, its temp file left) when the disk fills
    # during the write: every packet is checked against the free space first.
    from gevsim import _resources

    monkeypatch.setattr(_resources, "free_disk_bytes", lambda path: _resources.HEADROOM_BYTES + 10)
    out = tmp_path / "x.aedat4"
    assert main(["export", str(good), "--format", "aedat4", "--out", str(out)]) == 2
    assert capsys.readouterr().err == f"gevsim: error: {clipped(str(out))}: no space left on device\n"
    assert not out.exists() and leftovers(tmp_path) == []


def _abort():
    import faulthandler

    faulthandler.disable()  # pytest's handler would print this expected abort's stack into the log
    os.abort()


def _refuse():
    raise ValueError("refused in the child")


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork")
def test_a_writer_that_kills_its_process_only_kills_a_child(tmp_path, monkeypatch):
    # dv-processing aborts its process when a write fails from its own thread (a disk filling during export:
    # exit 134 and the stage left behind); in a child, the abort is an OSError here.
    from gevsim import _resources
    from gevsim.io._child import run_in_child

    assert run_in_child(sum, (1, 2), target=tmp_path) == 3
    with pytest.raises(ValueError, match="refused in the child"):
        run_in_child(_refuse, target=tmp_path)
    with pytest.raises(OSError, match="SIGABRT") as died:
        run_in_child(_abort, target=tmp_path)
    assert died.value.errno == errno.EIO and died.value.filename == str(tmp_path)
    monkeypatch.setattr(_resources, "free_disk_bytes", lambda path: 0)  # the child died on a full disk
    with pytest.raises(OSError) as full:
        run_in_child(_abort, target=tmp_path)
    assert full.value.errno == errno.ENOSPC


def self_stage(out: Path) -> Path:
    return out.parent / f".{out.name}.gevsim-abcd1234.tmp"


class FullExr:
    """OpenEXR whose writes into ``full`` fail as they do on a full disk (RuntimeError, not OSError)."""

    def __init__(self, full: Path):
        self.full = str(full)
        self.module = types.SimpleNamespace(ZIP_COMPRESSION=OpenEXR.ZIP_COMPRESSION,
                                            scanlineimage=OpenEXR.scanlineimage, File=self.file)

    def file(self, header, channels):
        real, full = OpenEXR.File(header, channels), self.full

        class File:
            def __enter__(self):
                return self

            def __exit__(self, *exc):
                return False

            def write(self, path):
                if path.startswith(full):
                    raise RuntimeError(f'Failed to write pixel data to image file "{path}". '
                                       "No space left on device.")
                real.write(path)

        return File()


def test_a_full_render_cache_goes_on_uncached(tmp_path, capsys, monkeypatch, caplog):
    # Before: OpenEXR's RuntimeError escaped the cache's (OSError, ConfigError) handler: traceback, exit 1.
    monkeypatch.setattr("gevsim.io.exr.OpenEXR", FullExr(tmp_path / "cache").module)
    out = tmp_path / "r"
    assert main(["render", str(DATA / "card.toml"), "--out", str(out), *SMALL, "--cache", str(tmp_path / "cache"),
                 "-q"]) == 0
    assert "going on without caching" in caplog.text and "No space left on device" in caplog.text
    assert (out / "basis").is_dir() and not list((tmp_path / "cache").rglob("*.exr"))
    assert leftovers(tmp_path) == []


def test_render_onto_a_full_disk_prints_one_line_and_keeps_the_earlier_output(tmp_path, capsys, monkeypatch):
    out = tmp_path / "r"
    args = ["render", str(DATA / "card.toml"), "--out", str(out), *SMALL, "--cache", str(tmp_path / "cache"), "-q"]
    assert main(args) == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    monkeypatch.setattr("gevsim.io.exr.OpenEXR", FullExr(tmp_path).module)
    assert main([*args, "--seed", "9"]) == 2
    assert capsys.readouterr().err.endswith(f"gevsim: error: {clipped(str(out))}: no space left on device\n")
    assert {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert leftovers(tmp_path) == []


def test_a_failed_flush_reported_as_runtime_error_is_one_line(tmp_path, capsys, monkeypatch):
    # h5py reports a failed flush as RuntimeError (the errno only in its text); study workers raised it as is.
    out, cfg = tmp_path / "run.h5", emulation(tmp_path)

    def flush(self):
        raise RuntimeError(f"Unable to synchronously flush file (file write failed: filename = '{self_stage(out)}', "
                           "errno = 28, error message = 'No space left on device')")

    monkeypatch.setattr("h5py.File.flush", flush)
    assert main(["emulate", str(cfg), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 2
    assert capsys.readouterr().err == f"gevsim: error: {clipped(str(out))}: no space left on device\n"
    assert not out.exists() and leftovers(tmp_path) == []
