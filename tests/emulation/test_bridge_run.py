"""A run with crossings between long steps (``crossings = "bridge"``) against the short steps it replaces."""

from pathlib import Path

import pytest

from gevsim.cli import main
from gevsim.emulation import load_config, run
from gevsim.io import EventReader

DATA = Path(__file__).parents[1] / "data"


def write(tmp_path, name, *, step_s, crossings, emulators=("dvs",), extra=""):
    path = tmp_path / name
    path.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nsensor = "davis346"\nseed = 4\n'
                    f'emulators = {list(emulators)!r}\nduration_s = 0.5\nstep_s = {step_s}\nframe_rate_hz = 0.0\n'
                    f'crossings = "{crossings}"\n{extra}[light]\nscale = 1e-4\n'.replace("'", '"'))
    return path


def test_a_bridged_run_keeps_the_short_steps_rate(tmp_path):
    """The card scene without flicker, dimmed to ~0.1 chip lux (~16 noise events per pixel and second): 1-ms
    steps with the bridge rule (one step each: 50x the short step) give the 20-us run's DVS rate within 8 %
    (measured 0.99 here; benchmarks/bridged_dvs.py for 0.1-1000 lux), and the file says how it was stepped."""
    short = run(load_config(write(tmp_path, "short.toml", step_s=2e-5, crossings="samples")), tmp_path / "short.h5",
                cache_dir=tmp_path / "cache", flicker=False)
    long = run(load_config(write(tmp_path, "long.toml", step_s=1e-3, crossings="bridge")), tmp_path / "long.h5",
               cache_dir=tmp_path / "cache", flicker=False)
    assert short.counts["events"] > 3000
    assert abs(long.counts["events"] / short.counts["events"] - 1.0) < 0.08, (long.counts, short.counts)
    with EventReader(tmp_path / "long.h5") as r:
        assert r.attrs["crossings"] == "bridge" and int(r.attrs["substeps"]) == 1


def test_a_bridged_run_splits_steps_longer_than_the_rule_holds(tmp_path):
    """A 5-ms step is split into sub-steps of at most 2 ms (BRIDGE_MAX_STEP_S); a noise-free run takes no twin."""
    cfg = load_config(write(tmp_path, "c.toml", step_s=5e-3, crossings="bridge"))
    run(cfg, tmp_path / "a.h5", cache_dir=tmp_path / "cache", flicker=False, noise=False)
    with EventReader(tmp_path / "a.h5") as r:
        assert int(r.attrs["substeps"]) == 3


@pytest.mark.parametrize("kwargs, text", [
    (dict(crossings="bridges"), "expected one of 'samples', 'bridge'"),
    (dict(crossings="bridge", emulators=("dvs", "gradient")), "the gradient emulator(s) take no bridge"),
    (dict(crossings="bridge", extra="cold_start = true\n"), "cold_start = false"),
])
def test_bad_crossing_configs_exit_2(tmp_path, capsys, kwargs, text):
    path = write(tmp_path, "bad.toml", step_s=1e-3, **kwargs)
    assert main(["emulate", str(path), "--out", str(tmp_path / "x.h5"), "--cache", str(tmp_path / "c"), "-q"]) == 2
    err = capsys.readouterr().err
    assert text in err and "emulation.crossings" in err and "Traceback" not in err
