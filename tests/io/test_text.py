"""Plain-text events: exact line format, lossless round trips, errors naming the file."""

import os

import hypothesis.extra.numpy as hnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim.errors import ConfigError
from gevsim.events.types import BRIGHTNESS_DTYPE, GRADIENT_DTYPE
from gevsim.io.text import export_text, import_text


def test_brightness_lines(tmp_path):
    ev = np.array([(3, 4, 100, True), (5, 6, 250, False)], dtype=BRIGHTNESS_DTYPE)
    export_text(tmp_path / "e.txt", ev)
    lines = (tmp_path / "e.txt").read_text().splitlines()
    assert lines[0].startswith("# t x y p ") and "axis" not in lines[0]
    assert lines[1:] == ["100 3 4 1", "250 5 6 0"]


def test_gradient_lines(tmp_path):
    ev = np.array([(3, 4, 100, -1, 1), (5, 6, 250, 1, 0)], dtype=GRADIENT_DTYPE)
    export_text(tmp_path / "g.txt", ev)
    lines = (tmp_path / "g.txt").read_text().splitlines()
    assert lines[0].startswith("# t x y p axis")
    assert lines[1:] == ["100 3 4 -1 1", "250 5 6 1 0"]


def events_strategy(gradient):
    n = st.integers(0, 400)
    return n.flatmap(lambda k: st.tuples(
        hnp.arrays(np.int64, k, elements=st.integers(0, 2**40)),
        hnp.arrays(np.int16, (k, 2), elements=st.integers(-(2**15), 2**15 - 1)),
        hnp.arrays(np.int8, k, elements=st.sampled_from([-1, 1])),
        hnp.arrays(np.uint8, k, elements=st.integers(0, 1))))


def build(parts, gradient):
    t, xy, p, axis = parts
    ev = np.zeros(len(t), dtype=GRADIENT_DTYPE if gradient else BRIGHTNESS_DTYPE)
    ev["t"], ev["x"], ev["y"] = np.sort(t), xy[:, 0], xy[:, 1]
    ev["p"] = p if gradient else p > 0
    if gradient:
        ev["axis"] = axis
    return ev


@settings(max_examples=25, deadline=None)
@given(parts=events_strategy(False))
def test_brightness_round_trip(tmp_path_factory, parts):
    ev = build(parts, False)
    path = tmp_path_factory.mktemp("t") / "b.txt"
    export_text(path, ev)
    back = import_text(path)
    assert back.dtype == BRIGHTNESS_DTYPE
    np.testing.assert_array_equal(back, ev)


@settings(max_examples=25, deadline=None)
@given(parts=events_strategy(True))
def test_gradient_round_trip(tmp_path_factory, parts):
    ev = build(parts, True)
    path = tmp_path_factory.mktemp("t") / "g.txt"
    export_text(path, ev)
    back = import_text(path)
    assert back.dtype == GRADIENT_DTYPE
    np.testing.assert_array_equal(back, ev)


def test_many_events_in_several_write_chunks(tmp_path, rng):
    n = 200_000  # more than one 2**16-line write
    ev = np.zeros(n, dtype=BRIGHTNESS_DTYPE)
    ev["t"] = np.sort(rng.integers(0, 10**9, n))
    ev["x"], ev["y"], ev["p"] = rng.integers(0, 640, n), rng.integers(0, 480, n), rng.random(n) < 0.5
    export_text(tmp_path / "m.txt", ev)
    np.testing.assert_array_equal(import_text(tmp_path / "m.txt"), ev)


def test_invalid_events_leave_no_file(tmp_path):
    with pytest.raises(TypeError):
        export_text(tmp_path / "x.txt", np.zeros(3))
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("body,match", [
    ("1 2 3\n", "expected 4 .* or 5 .* columns, got 3"),
    ("1 2 3 2\n", r"polarity must be one of \(0, 1\); bad event #0"),
    ("1 2 3 0 1\n2 2 3 1 0\n", r"polarity must be one of \(-1, 1\); bad event #0"),
    ("1 2 3 1 2\n", "axis must be 0 or 1"),
    ("5 2 3 1\n4 2 3 0\n", "non-decreasing; bad event #1"),
    ("1 70000 3 1\n", "int16"),
    ("1 a 3 1\n", "integer table"),
])
def test_bad_files_name_the_file(tmp_path, body, match):
    path = tmp_path / "bad.txt"
    path.write_text("# t x y p\n" + body)
    with pytest.raises(ConfigError, match=f"bad.txt: .*{match}"):
        import_text(path)


def test_the_e2vid_layout_starts_with_the_sensor_size(tmp_path):
    ev = np.array([(3, 4, 100, True), (5, 6, 250, False)], dtype=BRIGHTNESS_DTYPE)
    export_text(tmp_path / "e.txt", ev, seconds=True, e2vid_size=(346, 260))
    assert (tmp_path / "e.txt").read_text().splitlines() == ["346 260", "0.000100 3 4 1", "0.000250 5 6 0"]
    np.testing.assert_array_equal(import_text(tmp_path / "e.txt"), ev)
    export_text(tmp_path / "none.txt", ev[:0], seconds=True, e2vid_size=(346, 260))
    assert (tmp_path / "none.txt").read_text() == "346 260\n" and import_text(tmp_path / "none.txt").dtype == ev.dtype
    with pytest.raises(ValueError, match="brightness events"):
        export_text(tmp_path / "g.txt", np.ones(1, GRADIENT_DTYPE), seconds=True, e2vid_size=(4, 2))
    with pytest.raises(ValueError, match="two positive integers"):
        export_text(tmp_path / "z.txt", ev, seconds=True, e2vid_size=(0, 2))
    assert not (tmp_path / "g.txt").exists() and not (tmp_path / "z.txt").exists()
