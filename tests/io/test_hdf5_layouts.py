"""Issue 36, items 2, 3 and 7: HDF5 layouts of an event file.

Sealed reads: a dataset stored outside the file (external raw storage naming another file, an external
link into another HDF5 file, a virtual dataset, a soft link that does not resolve in the file) is refused
with one line naming the file and the dataset when the file is opened, before any data is read; the
exports then hold nothing of the other file (they used to copy its bytes verbatim, exit 0).
Every stream checked or ignored: a group of kind "events" with a stream's columns is checked like the
standard streams; one with other columns is left out of view and export. A hypothesis fuzz mixes these
layouts and checks that the reader returns only checked events or raises ConfigError.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from gevsim import cli
from gevsim.errors import ConfigError
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE, check_events
from gevsim.io import EventReader, EventWriter

W, H, T_END = 8, 4, 3000
SECRET = b"TOP-SECRET-" * 4000  # the other file's bytes: never to be read, let alone exported


def _events(dtype: np.dtype, n: int = 12) -> np.ndarray:
    rng = np.random.default_rng(len(dtype.names or ()))
    ev = np.zeros(n, dtype)
    ev["t"] = np.sort(rng.integers(0, T_END, n))
    ev["x"], ev["y"] = rng.integers(0, W, n), rng.integers(0, H, n)
    if "axis" in (dtype.names or ()):
        ev["p"], ev["axis"] = rng.choice([-1, 1], n), rng.integers(0, 2, n)
    else:
        ev["p"] = rng.random(n) < 0.5
    return ev


def _good(path: Path) -> Path:
    with EventWriter(path, width=W, height=H, config_toml="", seed=0) as w:
        w.append("events", _events(BRIGHTNESS_DTYPE))
        w.append("gradient_events", _events(GRADIENT_DTYPE))
        w.append_frame("log_photocurrent", np.zeros((H, W), np.float32), 0)
        w.close(t_end_us=T_END)
    return path


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> tuple[Path, Path, Path]:
    """A good file, and the two other files a crafted one may point at (a plain file, an HDF5 file)."""
    d = tmp_path_factory.mktemp("layouts")
    secret = d / "secret.bin"
    secret.write_bytes(SECRET)
    other = d / "other.h5"
    with h5py.File(other, "w") as f:
        f["leak"] = np.frombuffer(SECRET[:4096], np.uint8)
        for name, ev in (("events", _events(BRIGHTNESS_DTYPE)), ("gradient_events", _events(GRADIENT_DTYPE))):
            for field in ev.dtype.names:
                f[f"{name}/{field}"] = ev[field].astype(np.uint8) if field == "p" and name == "events" else ev[field]
    return _good(d / "good.h5"), secret, other


def _copy_stream(f: h5py.File, src: str, dst: str, fields: list[str]) -> h5py.Group:
    """A new group ``dst`` of kind "events" with ``src``'s ms_to_idx and the given columns of ``src``."""
    g = f.create_group(dst)
    g.attrs["kind"] = "events"
    g.attrs["fields"] = fields
    f.copy(f[f"{src}/ms_to_idx"], g, "ms_to_idx")
    for name in dict.fromkeys(fields):
        if name in f[src]:
            f.copy(f[f"{src}/{name}"], g, name)
    return g


def _replace(f: h5py.File, name: str, data: np.ndarray) -> None:
    attrs = dict(f[name].attrs)
    del f[name]
    f[name] = data
    f[name].attrs.update(attrs)


# -- sealed layouts: (name, edit(f, secret, other) -> the dataset or link the refusal names) --------------------
def _external_storage(f, secret, other, name):
    ds = f[name]
    shape, dtype, attrs = ds.shape, ds.dtype, dict(ds.attrs)
    del f[name]
    f.create_dataset(name, shape=shape, dtype=dtype, external=[(str(secret), 0, max(1, ds_bytes(shape, dtype)))])
    f[name].attrs.update(attrs)
    return name


def ds_bytes(shape, dtype) -> int:
    return int(np.prod(shape)) * np.dtype(dtype).itemsize


def _external_link(f, secret, other, name):
    del f[name]
    f[name] = h5py.ExternalLink(str(other), "/leak" if "/" in name else "/events")
    return name


def _virtual(f, secret, other, name):
    ds = f[name]
    n, dtype = ds.shape[0], ds.dtype
    del f[name]
    layout = h5py.VirtualLayout(shape=(n,), dtype=dtype)
    layout[:] = h5py.VirtualSource(str(other), "leak", shape=(4096,), dtype=np.uint8)[:n]
    f.create_virtual_dataset(name, layout)
    return name


def _soft_missing(f, secret, other, name):
    del f[name]
    f[name] = h5py.SoftLink("/nowhere/" + name)
    return name


SEALED = {"external raw storage": _external_storage, "external link": _external_link,
          "virtual dataset": _virtual, "dangling soft link": _soft_missing}


def _run(argv: list[str]) -> tuple[int, list[str]]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = cli.main(argv)
    return rc, err.getvalue().splitlines()


def _secret_anywhere(folder: Path, secret: Path) -> list[str]:
    """Files under ``folder`` (but the secret itself) holding the secret's bytes."""
    return [str(p) for p in folder.rglob("*") if p.is_file() and p != secret and b"TOP-SECRET-" in p.read_bytes()]


COMMANDS = {  # what a user runs on a crafted file: (argv after the file, the output it would write)
    "export npz": (["export", "--format", "npz", "--out"], "x.npz"),
    "export aedat4": (["export", "--format", "aedat4", "--out"], "x.aedat4"),
    "export text": (["export", "--format", "text", "--stream", "extra", "--out"], "x.txt"),
    "view": (["view", "--out"], "x.gif"),
}


def _command(name: str, path: Path, out_dir: Path) -> tuple[int, list[str], Path]:
    argv, out = COMMANDS[name]
    rc, err = _run([argv[0], str(path), *argv[1:], str(out_dir / out)])
    return rc, err, out_dir / out


@pytest.mark.parametrize("layout", sorted(SEALED))
def test_a_column_stored_outside_the_file_is_refused_in_one_line_and_nothing_of_it_exported(template, tmp_path,
                                                                                           layout):
    """The issue's case: an extra stream whose extra column is stored in another file (by absolute path)."""
    data, secret, other = template
    path = tmp_path / "crafted.h5"
    path.write_bytes(data.read_bytes())
    with h5py.File(path, "r+") as f:
        _copy_stream(f, "events", "extra", ["x", "y", "t", "p", "leak"])
        f["extra/leak"] = np.zeros(f["extra/t"].shape, np.uint8)
        SEALED[layout](f, secret, other, "extra/leak")
    for command in COMMANDS:
        rc, err, out = _command(command, path, tmp_path)
        assert rc == 2 and len(err) == 1, (command, err)
        assert err[0].startswith(f"gevsim: error: {path}: /extra/leak: "), (command, err)
        assert not out.exists(), command
    assert _secret_anywhere(tmp_path, secret) == []


@pytest.mark.parametrize("target", ["extra", "events/p", "frames/log_photocurrent/images"])
def test_an_external_link_into_another_hdf5_file_is_refused(template, tmp_path, target):
    data, secret, other = template
    path = tmp_path / "crafted.h5"
    path.write_bytes(data.read_bytes())
    with h5py.File(path, "r+") as f:
        if target == "extra":
            f["extra"] = h5py.ExternalLink(str(other), "/events")
        else:
            _external_link(f, secret, other, target)
    for command in ("view", "export npz", "export aedat4"):
        rc, err, out = _command(command, path, tmp_path)
        assert rc == 2 and len(err) == 1 and f"/{target}: is an external link to" in err[0], (command, err)
        assert not out.exists()
    assert _secret_anywhere(tmp_path, secret) == []


def test_the_refusal_comes_before_any_data_is_read(template, tmp_path, monkeypatch):
    data, secret, other = template
    path = tmp_path / "crafted.h5"
    path.write_bytes(data.read_bytes())
    with h5py.File(path, "r+") as f:
        _external_storage(f, secret, other, "frames/log_photocurrent/t")  # not even a stream: still refused
    reads = []
    original = h5py.Dataset.__getitem__
    monkeypatch.setattr(h5py.Dataset, "__getitem__", lambda self, sel: reads.append(self.name) or original(self, sel))
    with pytest.raises(ConfigError, match=rf"^{re.escape(str(path))}: /frames/log_photocurrent/t: is stored outside "
                                          r"the file \(external raw storage in 1 file\(s\), e\.g\. '/"):
        EventReader(path)
    assert reads == []


def test_a_soft_link_inside_the_file_reads_its_target(template, tmp_path):
    data, *_ = template
    path = tmp_path / "soft.h5"
    path.write_bytes(data.read_bytes())
    with h5py.File(path, "r+") as f:
        _copy_stream(f, "events", "extra", ["x", "y", "t"])
        f["extra"].attrs["fields"] = ["x", "y", "t", "p"]
        f["extra/p"] = h5py.SoftLink("/events/p")
    with EventReader(path) as r:
        np.testing.assert_array_equal(r.read("extra"), r.read("events"))


# -- every stream checked or ignored (item 3) -----------------------------------------------------------------
def _stream_case(f: h5py.File, case: str) -> None:
    if case == "x float 1e9":  # a brightness stream's columns, x stored as float
        g = _copy_stream(f, "events", "extra", ["x", "y", "t", "p"])
        _replace(f, "extra/x", np.where(np.arange(g["x"].shape[0]) == 0, 1e9, g["x"][()]).astype(np.float64))
    elif case == "axis 7, p 5":
        g = _copy_stream(f, "gradient_events", "extra", ["x", "y", "t", "p", "axis"])
        g["axis"][...], g["p"][...] = 7, 5
    elif case == "axis 7, p 5 as int64":
        g = _copy_stream(f, "gradient_events", "extra", ["x", "y", "t", "p", "axis"])
        _replace(f, "extra/axis", np.full(g["axis"].shape, 7, np.int64))
        _replace(f, "extra/p", np.full(g["p"].shape, 5, np.int64))
    elif case == "x float 1e9, another column":  # not a stream's columns: left out
        g = _copy_stream(f, "events", "extra", ["x", "y", "t", "p", "w"])
        _replace(f, "extra/x", np.full(g["x"].shape, 1e9))
        f["extra/w"] = np.zeros(g["t"].shape, np.float32)
    elif case == "no p column":
        _copy_stream(f, "events", "extra", ["x", "y", "t"])
    elif case == "p listed, missing":
        _copy_stream(f, "events", "extra", ["x", "y", "t"]).attrs["fields"] = ["x", "y", "t", "p"]


REFUSED = {"x float 1e9": "/extra: the columns must have dtype",
           "axis 7, p 5": "/extra: 12 gradient events have an axis other than 0 or 1",
           "axis 7, p 5 as int64": "/extra: the columns must have dtype",
           "p listed, missing": "/extra/p: is missing"}
LEFT_OUT = ("x float 1e9, another column", "no p column")


@pytest.mark.parametrize("case", [*REFUSED, *LEFT_OUT])
def test_a_non_standard_stream_is_checked_or_left_out(template, tmp_path, case):
    data, *_ = template
    path = tmp_path / "crafted.h5"
    path.write_bytes(data.read_bytes())
    with h5py.File(path, "r+") as f:
        _stream_case(f, case)
    for command in COMMANDS:
        rc, err, out = _command(command, path, tmp_path)
        if case in REFUSED or command == "export text":  # text names the stream: refused, or said left out
            want = REFUSED.get(case, "stream 'extra' is left out: its columns")
            assert rc == 2 and len(err) == 1 and want in err[0] and str(path) in err[0], (command, err)
            assert not out.exists()
            continue
        assert rc == 0, (command, err)
        out.unlink()
    if case in LEFT_OUT:  # the export holds the checked streams only
        assert _run(["export", str(path), "--format", "npz", "--out", str(tmp_path / "y.npz")])[0] == 0
        with np.load(tmp_path / "y.npz") as z:
            assert sorted(k for k in z.files if k.endswith("events") or k == "extra") == ["events", "gradient_events"]
            assert int(np.abs(z["events"]["x"]).max()) < W


# -- fuzz of the reader's layouts (item 7) ---------------------------------------------------------------------
TARGETS = ["events/x", "events/t", "events/p", "gradient_events/axis", "gradient_events/y", "events/ms_to_idx",
           "frames/log_photocurrent/images", "frames/log_photocurrent/t"]
PLAIN = ["valid", "soft link inside", "wrong dtype", "out of range", "missing column", "mismatched lengths"]


def _plain(f: h5py.File, kind: str, target: str, data: st.DataObject) -> None:
    """A layout that keeps every byte in the file: the reader returns checked data or refuses it."""
    if kind == "soft link inside":
        f.copy(f[target], f, "/copies/" + target.replace("/", "_"))
        del f[target]
        f[target] = h5py.SoftLink("/copies/" + target.replace("/", "_"))
    elif kind == "wrong dtype":
        v = f[target][()]
        _replace(f, target, v.astype(data.draw(st.sampled_from(["f8", "i1", "u8", "S4"]))))
    elif kind == "out of range":
        v = f[target][()].astype(np.float64 if f[target].dtype.kind == "f" else np.int64)
        v.reshape(-1)[data.draw(st.integers(0, v.size - 1))] = data.draw(st.sampled_from([-1, 7, 5, 10**4, 2**40]))
        _replace(f, target, v)
    elif kind == "missing column":
        del f[target]
    elif kind == "mismatched lengths":
        _replace(f, target, f[target][()][:-1])


def _extra_stream(f: h5py.File, data: st.DataObject) -> None:
    """A group of kind "events" with columns of the standard streams (and another), in any number and order."""
    src = data.draw(st.sampled_from(["events", "gradient_events"]))
    names = data.draw(st.lists(st.sampled_from(["x", "y", "t", "p", "axis", "w"]), min_size=1, max_size=6))
    g = _copy_stream(f, src, data.draw(st.sampled_from(["extra", "z_events"])), names)
    for name in set(names) - set(g):  # a column the source has not: floats far outside any range
        g[name] = np.full(f[f"{src}/t"].shape[0], 1e9)


@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_the_reader_returns_checked_events_or_one_config_error(template, tmp_path, data):
    raw, secret, other = template
    path = tmp_path / f"fuzz{len(list(tmp_path.iterdir()))}.h5"  # a new file each time (none is deleted)
    path.write_bytes(raw.read_bytes())
    sealed_broken: list[str] = []
    with h5py.File(path, "r+") as f:
        if data.draw(st.booleans()):
            _extra_stream(f, data)
        targets = data.draw(st.lists(st.sampled_from(TARGETS), min_size=1, max_size=3, unique=True))
        for target in targets:
            kind = data.draw(st.sampled_from(PLAIN + sorted(SEALED)))
            note(f"{kind} at {target}")
            if kind in SEALED:
                sealed_broken.append(SEALED[kind](f, secret, other, target))
            else:
                _plain(f, kind, target, data)
    if sealed_broken:  # refused at the open, naming the file and one of those datasets, before any read
        with pytest.raises(ConfigError) as caught:
            EventReader(path)
        assert str(caught.value).startswith(f"{path}: /") and any(f"/{n}: " in str(caught.value)
                                                                    for n in sealed_broken)
        return
    try:
        with EventReader(path) as r:
            for stream in r.streams:
                ev = r.read(stream)
                assert ev.dtype in (BRIGHTNESS_DTYPE, GRADIENT_DTYPE)
                check_events(ev, shape=(H, W))  # what kernels and writers rely on
                assert ev["t"].min(initial=0) >= 0 and ev["t"].max(initial=0) <= T_END
            for name in r.frame_names:
                images, t = r.frames(name)
                assert np.isfinite(images).all() and (np.diff(t) > 0).all()
            assert set(r.left_out).isdisjoint(r.streams)
    except ConfigError as exc:
        assert str(exc).startswith(str(path)) and "\n" not in str(exc)
