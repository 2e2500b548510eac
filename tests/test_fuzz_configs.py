"""Issue 24: a fuzz test of config values. Small valid configs (an emulation config, a sensor preset, a study
and a dataset config) get one key changed at a time: its value replaced by NaN, inf, -inf, 0, a negative or
huge number, 2**63, a string, an empty string, a list, a table or a bool; the key deleted; or an unknown key
added beside it. Then the command runs in-process through ``gevsim.cli.main`` and must end with exit 2 and one
``gevsim: error:`` line (the last on stderr) naming the file or the key, or with exit 0 and a well-formed
output: events inside the sensor and its time span (the reader's own checks), finite frames and a summary
without NaN. Never an exception out of main.

The emulation and preset targets run the emulation (16x12 px, 2 ms, one render shared by the module); the
study and dataset targets stop where the run would start (their executor), after every check of the config.
"""

from __future__ import annotations

import contextlib
import io
import math
import tempfile
import tomllib
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, example, given, note, settings
from hypothesis import strategies as st

from gevsim import cli

DATA = Path(__file__).parent / "data"
PRESET = Path(__file__).parents[1] / "noise" / "davis346.toml"
W, H = 16, 12

EMULATION = {
    "emulation": {"scene": str(DATA / "card.toml"), "sensor": "davis346",
                  "emulators": ["dvs", "gradient", "gradient_rc", "csdvs"], "seed": 1, "duration_s": 0.002,
                  "step_s": 2e-5, "chunk_steps": 50, "frame_rate_hz": 1000.0, "aps": True, "aps_exposure_s": 5e-4,
                  "cold_start": False},
    "render": {"width": W, "height": H, "spp": 1},
    "gradient": {"thresholds_ln": [0.05, 0.1, 0.2], "hysteresis_ln": 0.0},
    "csdvs": {"surround_length_px": 2.0, "surround_tau_s": 1e-3},
    "sensor": {"threshold_mismatch_ln": 0.03, "cutoff_hz": 2000.0},
    "light": {"scale": 1.0, "groups": {"lamp": {"scale": 2.0, "waveform": {"type": "pwm", "frequency_hz": 500.0,
                                                                             "duty": 0.5}}}},
}
STUDY = {
    "study": {"name": "fuzz", "scene": str(DATA / "card.toml"), "sensor": "ideal", "emulators": ["dvs", "gradient"],
              "flicker_group": "lamp", "duration_s": 0.002, "step_s": 2e-5, "frame_rate_hz": 1000.0, "seed": 0,
              "methods": ["dct", "direct"], "chunk_steps": 50, "repeats": 1,
              "render": {"width": W, "height": H, "spp": 1}},
    "sweep": {"waveform": ["pwm", "sinusoid"], "frequency_hz": [300.0], "duty": [0.5], "light_scale": [1.0],
              "threshold_mismatch_ln": [0.0], "thresholds_ln": [[0.1, 0.2]], "hysteresis_ln": [0.0]},
    "report": {"x": "waveform", "lines": "frequency_hz"},
}
DATASET = {
    "dataset": {"sequences": 2, "seed": 0, "scenes": [str(DATA / "card.toml")], "sensors": ["davis346"],
                "emulators": ["dvs"], "duration_s": 0.002, "step_s": 2e-5, "chunk_steps": 50, "frame_rate_hz": 500.0,
                "evreal": True, "render": {"width": W, "height": H, "spp": 1},
                "randomize": {"waveforms": ["pwm", "sinusoid"], "frequency_hz": [100.0, 2000.0], "duty": [0.1, 0.9],
                              "modulation": [0.2, 1.0], "mains_hz": [50.0, 60.0], "light_scale": [0.1, 10.0]}},
}

#: What a value is replaced by: non-finite, zero, negative, huge, out of int64, and values of other types.
VALUES = [math.nan, math.inf, -math.inf, 0, 0.0, -1, -1e-3, 1e300, -1e300, 2**63, "x", "", [], [1.0, "a"],
          {"a": 1}, True, False]
DELETE, UNKNOWN = "<delete>", "<unknown key>"
MUTATIONS = VALUES + [DELETE, UNKNOWN]


def _paths(tree, prefix: tuple = ()) -> Iterator[tuple]:
    """Every key (and list item) of a parsed TOML tree, tables included, as a path of keys and indices."""
    items = tree.items() if isinstance(tree, dict) else enumerate(tree) if isinstance(tree, list) else ()
    for key, value in items:
        yield prefix + (key,)
        yield from _paths(value, prefix + (key,))


def _mutated(tree: dict, path: tuple, mutation) -> dict:
    import copy

    tree = copy.deepcopy(tree)
    parent = tree
    for key in path[:-1]:
        parent = parent[key]
    if mutation == UNKNOWN:
        target = parent[path[-1]]
        if isinstance(target, dict):  # a table: a key inside it; a value: one beside it
            target["fuzz_unknown"] = 1.0
        elif isinstance(parent, dict):
            parent["fuzz_unknown"] = 1.0
        else:
            parent.append(1.0)  # one more item in a list
    elif mutation == DELETE:
        del parent[path[-1]]
    else:
        parent[path[-1]] = mutation
    return tree


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = cli.main(argv)
    return rc, out.getvalue(), err.getvalue()


def _check_refusal(err: str, names: list[str]) -> None:
    """Exit 2's stderr: its last line is the one error line, naming one of ``names`` (file or key)."""
    lines = err.splitlines()
    assert "Traceback" not in err and lines, err
    assert [line for line in lines if line.startswith("gevsim: error: ")] == [lines[-1]], err
    assert any(name in lines[-1] for name in names), (lines[-1], names)


def _check_emulation(out: Path, stdout: str) -> None:
    """An emulation file that reads back (the reader checks every event's range), with finite frames and a
    summary table without NaN or inf."""
    from gevsim.io import EventReader

    assert "nan" not in stdout and "inf" not in stdout, stdout
    with EventReader(out) as f:
        assert f.attrs["width"] >= 1 and f.attrs["height"] >= 1 and f.streams  # the scene's own size without [render]
        for stream in f.streams:
            ev = f.read(stream)
            assert np.all(np.diff(ev["t"].astype(np.int64)) >= 0)
        for name in f.frame_names:
            images, t = f.frames(name)
            assert np.isfinite(images).all() and np.isfinite(t).all(), name


def _key_names(path: tuple) -> list[str]:
    """What an error about ``path`` may name: its dotted key or its last key (lists: the list's key)."""
    keys = [str(k) for k in path if not isinstance(k, int)]
    return [".".join(keys), keys[-1], "fuzz_unknown"]


FUZZ = dict(deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                     HealthCheck.too_slow])


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> Path:
    """The render cache, filled once with the scene's 16x12 render; the unchanged config runs."""
    tmp = tmp_path_factory.mktemp("fuzz_configs")
    cfg = tmp / "em.toml"
    cfg.write_text(tomli_w.dumps(EMULATION))
    rc, stdout, err = _run(["emulate", str(cfg), "--out", str(tmp / "good.h5"), "--cache", str(tmp / "c"), "-q"])
    assert rc == 0, err
    _check_emulation(tmp / "good.h5", stdout)
    return tmp / "c"


def _emulate(config: dict, cache: Path, names: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        cfg, out = Path(tmp) / "em.toml", Path(tmp) / "out.h5"
        cfg.write_text(tomli_w.dumps(config))
        rc, stdout, err = _run(["emulate", str(cfg), "--out", str(out), "--cache", str(cache), "-q"])
        note(f"rc {rc}; stderr: {err[-400:]}")
        assert rc in (0, 2), err
        if rc == 2:
            _check_refusal(err, [str(cfg), *names])
            assert not out.exists()
        else:
            _check_emulation(out, stdout)


@given(path=st.sampled_from(sorted(_paths(EMULATION), key=str)), mutation=st.sampled_from(MUTATIONS))
@example(path=("csdvs", "surround_length_px"), mutation=1e300)  # NaN signal after the render
@example(path=("light", "groups", "lamp", "waveform", "frequency_hz"), mutation=1e300)  # 1e297 sub-steps
@example(path=("light", "scale"), mutation=1e300)  # infinite photocurrent after the render
@example(path=("light", "groups", "lamp", "scale"), mutation=1e300)
@settings(max_examples=60, **FUZZ)
def test_a_mutated_emulation_config_is_refused_in_one_line_or_runs(cache, path, mutation):
    note(f"{'.'.join(map(str, path))} <- {mutation!r}")
    _emulate(_mutated(EMULATION, path, mutation), cache, _key_names(path))


PRESET_TREE = tomllib.loads(PRESET.read_text())


@given(path=st.sampled_from(sorted(_paths(PRESET_TREE), key=str)), mutation=st.sampled_from(MUTATIONS))
@example(path=("noise", "dark_current_a"), mutation=1e-26)  # NaN in black pixels after the render
@example(path=("noise", "amplifier_noise_ln2_hz"), mutation=1e300)  # -inf signal
@example(path=("readout", "latency_jitter_s"), mutation=1e300)  # int64 timestamps overflowed
@example(path=("events", "refractory_s"), mutation=2**63)  # too big for the compiled kernel's int64
@settings(max_examples=60, **FUZZ)
def test_a_mutated_sensor_preset_is_refused_in_one_line_or_runs(cache, path, mutation):
    note(f"{'.'.join(map(str, path))} <- {mutation!r}")
    with tempfile.TemporaryDirectory() as tmp:
        preset = Path(tmp) / "fuzz_preset.toml"
        preset.write_text(tomli_w.dumps(_mutated(PRESET_TREE, path, mutation)))
        config = _mutated(EMULATION, ("emulation", "sensor"), str(preset))
        _emulate(config, cache, [str(preset), *_key_names(path)])


class _Loaded(Exception):
    """Raised where the run would start: every check of the config has passed."""


def _load_only(command: str, config: dict, path: tuple, monkeypatch, cache: Path) -> None:
    from gevsim.experiments import executors

    def stop(*args, **kwargs):
        raise _Loaded

    monkeypatch.setattr(executors, "make_executor", stop)
    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(tmp) / f"{command}.toml"
        cfg.write_text(tomli_w.dumps(config))
        try:
            rc, _, err = _run([command, str(cfg), "--out", str(Path(tmp) / "out"), "--cache", str(cache), "-q"])
        except _Loaded:
            return
        assert rc == 2, err
        _check_refusal(err, [str(cfg), *_key_names(path)])


@given(path=st.sampled_from(sorted(_paths(STUDY), key=str)), mutation=st.sampled_from(MUTATIONS))
@example(path=("report", "x"), mutation=[])  # TypeError: unhashable
@settings(max_examples=150, **FUZZ)
def test_a_mutated_study_config_is_refused_in_one_line_or_loads(cache, monkeypatch, path, mutation):
    note(f"{'.'.join(map(str, path))} <- {mutation!r}")
    _load_only("study", _mutated(STUDY, path, mutation), path, monkeypatch, cache)


@given(path=st.sampled_from(sorted(_paths(DATASET), key=str)), mutation=st.sampled_from(MUTATIONS))
@settings(max_examples=150, **FUZZ)
def test_a_mutated_dataset_config_is_refused_in_one_line_or_loads(cache, monkeypatch, path, mutation):
    note(f"{'.'.join(map(str, path))} <- {mutation!r}")
    _load_only("dataset", _mutated(DATASET, path, mutation), path, monkeypatch, cache)


def test_a_scene_without_light_reports_a_render_error_of_0_not_nan(tmp_path):
    """Every light group at luminance 0: the render is black, and its noise is none (it printed 'p99 ln error
    nan' and wrote NaN into manifest.json)."""
    import json
    import shutil

    shutil.copy(DATA / "card.py", tmp_path / "card.py")
    text = (DATA / "card.toml").read_text()
    for old, new in (("width = 32", f"width = {W}"), ("height = 24", f"height = {H}"), ("spp = 4", "spp = 1"),
                     ("luminance_cd_m2 = 1e5", "luminance_cd_m2 = 0.0")):
        assert old in text
        text = text.replace(old, new)
    (tmp_path / "dark.toml").write_text(text)
    rc, _, err = _run(["render", str(tmp_path / "dark.toml"), "--out", str(tmp_path / "out"), "--cache",
                       str(tmp_path / "c"), "-q"])
    assert rc == 0 and "p99 ln error 0;" in err, err
    manifest = (tmp_path / "out" / "manifest.json").read_text()
    assert "NaN" not in manifest and json.loads(manifest)["render_noise"]["se_ln"]["p99"] == 0.0
