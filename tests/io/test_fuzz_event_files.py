"""Issue 24: a fuzz test of the commands that read an emulation file. One good small file is corrupted at
random (a column, index, frame, threshold or attribute set to NaN, huge, negative or out-of-range values,
reordered, deleted, truncated, stored with another dtype, or a compressed chunk damaged), then `reconstruct`
and `export` run in-process. Each must end with exit 2 and exactly one `gevsim: error:` line naming the file,
or with exit 0 and the output the good file gives (the corruption was harmless); never an exception out of
main, a signal, or exit 0 with another output.

Only corruptions that make the file invalid, or leave what the commands read unchanged, are drawn: a valid
file with other values (an x moved inside the sensor, a stream without its ``kind`` marker, which is a file
without that stream) is a different input, not a corrupt one.
"""

import contextlib
import io
import json
import shutil
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from gevsim import cli

DATA = Path(__file__).parents[1] / "data"
W, H = 24, 18

pytest.importorskip("dv_processing")


def _run(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = cli.main(argv)
    return rc, err.getvalue()


def _outputs(path: Path, tmp: Path) -> tuple[tuple[int, str], tuple[int, str], dict | None, dict | None]:
    """(rc, stderr) of reconstruct and export of ``path``, and what they wrote (None where nothing)."""
    from gevsim.io.aedat4 import read_aedat4

    rec, x = tmp / "rec", tmp / "x.aedat4"
    r1 = _run(["reconstruct", str(path), "--method", "dct,direct", "--out", str(rec), "-q"])
    r2 = _run(["export", str(path), "--format", "aedat4", "--out", str(x)])
    metrics = None
    if (rec / "metrics.json").exists():
        metrics = json.loads((rec / "metrics.json").read_text())
        metrics["summary"].pop("source")
    events = {k: v.tolist() for k, v in read_aedat4(x).items()} if x.exists() else None
    return r1, r2, metrics, events


@pytest.fixture(scope="module")
def good_outputs(good, tmp_path_factory):
    """The good file (tests/io/conftest.py: W x H px), its reconstruction metrics and exported events."""
    tmp = tmp_path_factory.mktemp("fuzz")
    shutil.copy(good, tmp / "good.h5")
    (r1, _), (r2, _), metrics, events = _outputs(tmp / "good.h5", tmp)
    assert r1 == r2 == 0 and metrics is not None and events is not None
    assert sum(len(v) for v in events.values()) > 100  # the good file has events to lose
    with h5py.File(tmp / "good.h5", "r") as f:
        t_end = int(f.attrs["t_end_us"])
    return tmp / "good.h5", metrics, events, t_end


# Values outside each dataset's valid set (a valid value would make a different, not a corrupt, file).
def _bad_values(t_end: int) -> dict[str, list]:
    return {
        "events/x": [-1, W, 32767, -32768], "events/y": [-1, H, 32767], "events/p": [2, 7, 255],
        "events/t": [-1, t_end + 1, 2**62], "events/ms_to_idx": [-5, 10**12, 2**40],
        "gradient_events/x": [-1, W, 32767], "gradient_events/y": [-20000, H],
        "gradient_events/p": [0, 2, 7, -128], "gradient_events/axis": [2, 120, 255],
        "gradient_events/t": [-1, t_end + 1, 2**62], "gradient_events/ms_to_idx": [-1, 10**12],
        "frames/log_photocurrent/images": [np.nan, np.inf, -np.inf],
        "frames/log_photocurrent/t": [-1, t_end + 1, 2**62],
        "thresholds/gradient": [np.nan, 0.0, -0.1, np.inf],
        "initial_state/gradient": [2, -2, 100, -128],
    }


#: (object, attribute) -> values that are wrong (or harmless where the commands do not use the attribute).
ATTRS: dict[tuple[str, str], list] = {
    ("/", "width"): [0, -5, W + 1, W - 1, 2**40, "abc", 1.5],
    ("/", "height"): [0, -1, H + 2, 2**40, "18"],
    ("/", "t_end_us"): [-1, -1000, 2**62, 2**40, "4000", 4000.5],
    ("/", "format"): ["gevsim-events-9", 3],
    ("/", "complete"): [False, 0],
    ("/", "seed"): ["x", -1, 2**40],  # not used by these commands: harmless
    ("events", "fields"): [["x", "y", "q"], ["x", "y", "p"], ["y", "x", "t", "p"], "x"],
    ("gradient_events", "fields"): [["x", "y", "t", "p"], ["x", "y", "t", "p", "axis", "axis"], ["t", "ms_to_idx"]],
    ("events/p", "numpy_dtype"): ["int8"],
}


def _corrupt(path: Path, data: st.DataObject, t_end: int) -> str:
    """Apply one random corruption to the file at ``path``; returns what was done."""
    kind = data.draw(st.sampled_from(["value", "value", "order", "delete", "truncate", "dtype", "chunk", "attr",
                                      "del_attr"]))
    with h5py.File(path, "r+") as f:
        if kind in ("attr", "del_attr"):
            obj, key = data.draw(st.sampled_from(sorted(ATTRS)))
            if kind == "del_attr":
                del f[obj].attrs[key]
                return f"del {obj} attr {key}"
            value = data.draw(st.sampled_from(ATTRS[obj, key]))
            f[obj].attrs[key] = value
            return f"{obj} attr {key} = {value!r}"
        bad = _bad_values(t_end)
        name = data.draw(st.sampled_from(sorted(bad)))
        ds = f[name]
        v = ds[()]
        if kind == "value" and v.size:
            value = data.draw(st.sampled_from(bad[name]))
            flat = v.reshape(-1).copy()
            where = data.draw(st.lists(st.integers(0, flat.size - 1), min_size=1, max_size=5))
            info = np.iinfo(v.dtype) if v.dtype.kind in "iu" else None
            if info is not None and not info.min <= value <= info.max:  # store what the dtype can hold
                ds2 = f.create_dataset(name + "_wide", data=flat.astype(np.int64).reshape(v.shape))
                del f[name]
                f.move(ds2.name, name)
                ds, flat = f[name], flat.astype(np.int64)
            flat[where] = value
            ds[...] = flat.reshape(v.shape)
            return f"{name}[{where}] = {value}"
        if kind == "order" and name.endswith("/t") and len(np.unique(v)) > 1:
            ds[...] = v[::-1]
            return f"{name} reversed"
        if kind == "delete" and not name.startswith("thresholds/dvs"):
            del f[name]
            return f"del {name}"
        if kind == "truncate" and v.ndim >= 1 and v.shape[0] > 1:
            n = data.draw(st.integers(0, v.shape[0] - 1))
            del f[name]
            f.create_dataset(name, data=v[:n])
            return f"{name} truncated to {n}"
        if kind == "dtype":
            new = data.draw(st.sampled_from(["f8", "i1", "S4", "u8"]))
            del f[name]
            f.create_dataset(name, data=v.astype(new) if new != "S4" else np.full(v.shape, b"ab", "S4"))
            return f"{name} stored as {new}"
        if kind == "chunk" and ds.chunks and ds.compression and ds.id.get_num_chunks():
            info = ds.id.get_chunk_info(data.draw(st.integers(0, ds.id.get_num_chunks() - 1)))
            at = info.byte_offset + data.draw(st.integers(0, max(info.size - 8, 0)))
            f.close()
            with open(path, "r+b") as fh:
                fh.seek(at)
                fh.write(b"\xde\xad\xbe\xef\x00\xff\x13\x37")
            return f"{name}: chunk bytes at {at} damaged"
    return "nothing"


@settings(max_examples=50, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_corrupted_files_end_in_one_line_or_the_good_output(good_outputs, data):
    path0, metrics0, events0, t_end = good_outputs
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        path = tmp / "corrupt.h5"
        shutil.copyfile(path0, path)
        what = _corrupt(path, data, t_end)
        note(what)
        (r1, e1), (r2, e2), metrics, events = _outputs(path, tmp)
        for rc, err, out, want in ((r1, e1, metrics, metrics0), (r2, e2, events, events0)):
            assert rc in (0, 2), (what, err)
            if rc == 2:
                lines = [line for line in err.splitlines() if line.startswith("gevsim: error: ")]
                assert len(lines) == 1 and str(path) in lines[0] and "Traceback" not in err, (what, err)
                assert out is None, what  # nothing written
            else:
                assert out == want, what  # harmless corruption: the good file's output
