"""The emulation driver end to end on tiny scenes: outputs, chunking, seeds, counterfactuals."""

import dataclasses
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.emulation import RunSummary, StreamStats, load_config, run
from gevsim.errors import ConfigError
from gevsim.io import EventReader

DATA = Path(__file__).parents[1] / "data"
STREAMS = ("events", "gradient_events", "gradient_rc_events", "csdvs_events")


def config(tmp_path, scene="card.toml", sensor="davis346", name="run.toml", **emulation):
    fields = {"scene": str(DATA / scene), "sensor": sensor, "seed": 4, "step_s": 2e-5, "chunk_steps": 50,
              "frame_rate_hz": 1000.0, **emulation}
    lines = ["[emulation]"]
    for key, value in fields.items():
        lines.append(f"{key} = {value!r}".replace("'", '"').replace("True", "true").replace("False", "false"))
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def read_all(path):
    with EventReader(path) as r:
        return {s: r.read(s) for s in r.streams}, r


@pytest.mark.slow
def test_outputs_and_summary(tmp_path):
    cfg = load_config(config(tmp_path, aps=True, aps_exposure_s=5e-4))
    summary = run(cfg, tmp_path / "out.h5", cache_dir=tmp_path / "cache")
    events, reader = read_all(tmp_path / "out.h5")
    assert set(events) == set(STREAMS)
    assert isinstance(summary, RunSummary) and summary.out == str(tmp_path / "out.h5")
    assert {k: len(v) for k, v in events.items()} == summary.counts
    assert summary.steps == 200 and (summary.width, summary.height) == (32, 24) and summary.frames == 5
    assert summary["counts"] == summary.counts and summary.as_dict()["steps"] == 200  # read-only dict access
    with pytest.raises(KeyError):
        summary["nope"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        summary.steps = 1
    with EventReader(tmp_path / "out.h5") as r:
        assert "log_photocurrent" in r.frame_names and "aps" in r.frame_names
        images, t_us = r.frames("log_photocurrent")
        assert images.shape == (5, 24, 32) and list(t_us) == [0, 1000, 2000, 3000, 4000]
        aps, aps_t = r.frames("aps")
        assert aps.dtype == np.uint16 and list(aps_t) == [1000, 2000, 3000, 4000]
        assert r.seed == 4 and 'scene = "' in r.config_toml
        theta = r.array("/thresholds/gradient")
        assert theta.shape == (2, 24, 32)


@pytest.mark.slow
def test_chunking_does_not_change_the_events(tmp_path):
    a = run(load_config(config(tmp_path, chunk_steps=7, name="a.toml")), tmp_path / "a.h5", cache_dir=tmp_path / "c")
    b = run(load_config(config(tmp_path, chunk_steps=200, name="b.toml")), tmp_path / "b.h5", cache_dir=tmp_path / "c")
    ea, _ = read_all(tmp_path / "a.h5")
    eb, _ = read_all(tmp_path / "b.h5")
    assert sum(a["counts"].values()) > 100
    for s in STREAMS:
        np.testing.assert_array_equal(ea[s], eb[s])
    assert a["counts"] == b["counts"]


def test_seed_determinism(tmp_path):
    runs = []
    for name, seed in (("a", 4), ("b", 4), ("c", 5)):
        run(load_config(config(tmp_path, name=f"{name}.toml", seed=seed)), tmp_path / f"{name}.h5",
            cache_dir=tmp_path / "c")
        runs.append(read_all(tmp_path / f"{name}.h5")[0])
    for s in STREAMS:
        np.testing.assert_array_equal(runs[0][s], runs[1][s])
    assert not np.array_equal(runs[0]["events"], runs[2]["events"])


def test_static_scene_without_flicker_and_noise_gives_no_events(tmp_path):
    summary = run(load_config(config(tmp_path)), tmp_path / "o.h5", cache_dir=tmp_path / "c", flicker=False,
                  noise=False)
    assert sum(summary.counts.values()) == 0


@pytest.mark.slow
def test_uniform_flicker_leaks_into_gradients_only_through_finite_bandwidth(tmp_path):
    """One lamp lights everything: with an infinitely fast ideal pixel the log image only
    shifts, so there are no gradient events while the DVS fires; with the finite,
    light-dependent bandwidth of a real photoreceptor (noise off) dim pixels lag the bright
    ones and gradients flicker (DESIGN.md, Photoreceptor)."""
    ideal = run(load_config(config(tmp_path, sensor="ideal", name="i.toml")), tmp_path / "i.h5",
                cache_dir=tmp_path / "c")
    assert ideal["counts"]["gradient_events"] == 0 and ideal["counts"]["gradient_rc_events"] == 0
    assert ideal["counts"]["events"] > 32 * 24 * 4  # several events per pixel over 4 flicker periods
    slow = run(load_config(config(tmp_path, name="s.toml")), tmp_path / "s.h5", cache_dir=tmp_path / "c",
               noise=False)
    assert slow["counts"]["gradient_events"] > 0


@pytest.mark.slow
def test_cli_emulate_and_frame_mode(tmp_path, capsys):
    cfg = config(tmp_path)
    assert main(["emulate", str(cfg), "--out", str(tmp_path / "x.h5"), "--cache", str(tmp_path / "c"), "-q"]) == 0
    table = capsys.readouterr().out
    assert "gradient_events" in table and "events/s" in table
    # Made, delivered and lost per stream, and made = delivered + lost (the readout's conservation).
    with EventReader(tmp_path / "x.h5") as r:
        readout = json.loads(r.attrs["readout_json"])
        delivered = {s: len(r.read(s)) for s in readout}
    for line in table.splitlines()[1:]:
        name, made, got, lost = line.split()[:4]
        assert int(got) == delivered[name] and int(made) == readout[name]["requested"] == int(got) + int(lost)
    # Frame mode from a folder of PNGs.
    import imageio.v3 as iio

    frames = tmp_path / "frames"
    frames.mkdir()
    rng = np.random.default_rng(0)
    base = rng.integers(0, 200, (24, 32))
    for k in range(5):
        iio.imwrite(frames / f"f{k:02d}.png", np.clip(base + 10 * k * (np.arange(32) > 16), 0, 255).astype(np.uint8))
    assert main(["emulate", "--frames", str(frames), "--fps", "30", "--out", str(tmp_path / "f.h5")]) == 0
    with EventReader(tmp_path / "f.h5") as r:
        assert len(r.read("gradient_events")) > 0 and r.frames("intensity")[0].shape == (5, 24, 32)


@pytest.mark.parametrize(
    "emulation, text",
    [
        (dict(emulators=["dvs", "gradiant"]), "did you mean 'gradient'"),
        (dict(step_s=1.0), "step_s"),
        (dict(sensor="davis347"), "did you mean 'davis346'"),
        (dict(aps=True, sensor="dvs128"), "no [aps] table"),
    ],
)
def test_bad_configs_exit_2(tmp_path, capsys, emulation, text):
    cfg = config(tmp_path, **emulation)
    assert main(["emulate", str(cfg), "--out", str(tmp_path / "x.h5"), "--cache", str(tmp_path / "c"), "-q"]) == 2
    err = capsys.readouterr().err
    assert text in err and err.count("\n") == 1
    assert not (tmp_path / "x.h5").exists() and not list(tmp_path.glob(".x.h5*"))


def test_config_errors_name_the_key(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[emulation]\nscene = "office"\nstep_us = 1\n')
    with pytest.raises(ConfigError, match=r"emulation\.step_us.*did you mean 'step_s'"):
        load_config(path)


@pytest.mark.slow
def test_summary_reads_back_in_windows_the_same_statistics(tmp_path, monkeypatch):
    from gevsim.emulation import summary as summary_mod
    from gevsim.events import event_probability

    run(load_config(config(tmp_path, frame_rate_hz=2000.0)), tmp_path / "o.h5", cache_dir=tmp_path / "c")
    monkeypatch.setattr(summary_mod, "BATCH_FRAMES", 3)  # several windows
    monkeypatch.setattr("gevsim.io.event_reader.WINDOW_EVENTS", 40)  # and fewer frames where they hold more events
    stats = summary_mod.summarize(tmp_path / "o.h5")
    with EventReader(tmp_path / "o.h5") as r:
        frame_t = r.frames("log_photocurrent")[1]
        for stream in STREAMS:
            ev = r.read(stream)
            p = event_probability(ev, frame_t, width=32, height=24)
            assert isinstance(stats[stream], StreamStats) and stats[stream].count == len(ev)
            assert stats[stream].event_probability == pytest.approx(p.mean())
            assert stats[stream]["count"] == stats[stream].count  # read-only dict access


@pytest.mark.slow
def test_light_overrides_need_no_rerender_and_act_linearly(tmp_path):
    base = load_config(config(tmp_path, sensor="ideal"))
    run(base, tmp_path / "a.h5", cache_dir=tmp_path / "c")
    brighter = dataclasses.replace(base, light_scale=2.0, text="")
    run(brighter, tmp_path / "b.h5", cache_dir=tmp_path / "c")
    with EventReader(tmp_path / "a.h5") as a, EventReader(tmp_path / "b.h5") as b:
        la, lb = a.frames("log_photocurrent")[0], b.frames("log_photocurrent")[0]
        assert "scale = 2.0" in b.config_toml
    bright = la[0] > np.median(la[0])  # where the photocurrent dwarfs the dark current
    np.testing.assert_allclose((lb - la)[:, bright], np.log(2.0), atol=2e-3)
    steady = dataclasses.replace(base, group_waveform={"lamp": {"type": "dc"}}, text="")
    s = run(steady, tmp_path / "s.h5", cache_dir=tmp_path / "c")
    assert sum(s["counts"].values()) == 0  # static scene, steady lamp, ideal pixel
    bad = dataclasses.replace(base, group_scale={"lamps": 0.5})
    with pytest.raises(ConfigError, match="did you mean 'lamp'"):
        run(bad, tmp_path / "x.h5", cache_dir=tmp_path / "c")


def test_programmatic_config_round_trips_through_toml(tmp_path):
    cfg = dataclasses.replace(load_config(config(tmp_path)), light_scale=0.5, group_scale={"lamp": 0.25},
                              group_waveform={"lamp": {"type": "pwm", "frequency_hz": 300.0, "duty": 0.5}})
    path = tmp_path / "round.toml"
    path.write_text(cfg.to_toml())
    back = load_config(path)
    for field in ("scene", "sensor", "seed", "step_s", "light_scale", "group_scale", "group_waveform",
                  "thresholds_ln", "emulators"):
        assert getattr(back, field) == getattr(cfg, field), field


def test_to_toml_orders_light_groups_by_name_not_by_set_order(tmp_path):
    """Issue 24 #18: shard metadata (config_toml) must not follow PYTHONHASHSEED."""
    names = ["zeta", "b", "lamp", "a9", "m", "q", "c", "x"]  # 8! orders: set order is sorted by chance 1 in 40320
    cfg = dataclasses.replace(load_config(config(tmp_path)), group_scale={n: 0.5 for n in names[:5]},
                              group_waveform={n: {"type": "dc"} for n in reversed(names[3:])})
    text = cfg.to_toml()
    assert list(tomllib.loads(text)["light"]["groups"]) == sorted(names)
    assert dataclasses.replace(cfg, group_scale=dict(reversed(cfg.group_scale.items()))).to_toml() == text


def test_pose_blend_of_the_photocurrent_basis():
    """Between poses the photocurrent is the linear blend of the two poses' mixes."""
    from gevsim.emulation.driver import Setup, photocurrent_at

    rng = np.random.default_rng(0)
    basis = rng.random((3, 2, 4, 5))  # 3 poses, 2 light groups
    setup = Setup(None, None, np.array([0.0, 1.0, 3.0]), basis, (), 3.0, None)
    t = np.array([0.0, 0.25, 1.0, 2.5, 3.0])
    w = rng.random((5, 2))
    got = photocurrent_at(setup, t, w)
    for k, tk in enumerate(t):
        i = min(int(np.searchsorted([0.0, 1.0, 3.0], tk, side="right")) - 1, 1)
        a = (tk - [0.0, 1.0, 3.0][i]) / ([1.0, 2.0][i])
        expect = np.tensordot(w[k], (1 - a) * basis[i] + a * basis[i + 1], axes=1)
        np.testing.assert_allclose(got[k], expect, rtol=1e-12)


@pytest.mark.parametrize("emulation, text", [
    (dict(step_s=2.4e-5), "not a whole number of steps"),
])
def test_time_grid_must_tile_the_duration(tmp_path, capsys, emulation, text):
    cfg = config(tmp_path, **emulation)
    assert main(["emulate", str(cfg), "--out", str(tmp_path / "x.h5"), "--cache", str(tmp_path / "c"), "-q"]) == 2
    assert text in capsys.readouterr().err


def test_hysteresis_and_rc_size_are_checked_before_rendering(tmp_path, capsys):
    cfg = config(tmp_path)
    cfg.write_text(cfg.read_text() + "[gradient]\nthresholds_ln = [0.05]\nhysteresis_ln = 0.05\n")
    assert main(["emulate", str(cfg), "--out", str(tmp_path / "x.h5"), "--cache", str(tmp_path / "c"), "-q"]) == 2
    assert "gradient.hysteresis_ln" in capsys.readouterr().err
    odd = config(tmp_path, name="odd.toml")
    odd.write_text(odd.read_text() + "[render]\nwidth = 31\n")
    assert main(["emulate", str(odd), "--out", str(tmp_path / "y.h5"), "--cache", str(tmp_path / "c"), "-q"]) == 2
    assert "even width and height" in capsys.readouterr().err and not (tmp_path / "c").exists()


@pytest.mark.slow
def test_summary_rates_in_windows_equal_whole_stream_rates(tmp_path, monkeypatch):
    from gevsim.emulation import summary as summary_mod
    from gevsim.events import event_rates

    run(load_config(config(tmp_path)), tmp_path / "o.h5", cache_dir=tmp_path / "c")
    monkeypatch.setattr("gevsim.io.event_reader.WINDOW_EVENTS", 50)  # several windows over the 4 ms run
    stats = summary_mod.summarize(tmp_path / "o.h5")
    with EventReader(tmp_path / "o.h5") as r:
        for stream in STREAMS:
            whole = event_rates(r.read(stream), r.t_end_us / 1e6, width=32, height=24)
            assert stats[stream].rates_hz == pytest.approx(whole)


def test_render_noise_floor_is_zero_without_render_noise_and_positive_with_it(tmp_path):
    """The floor run alternates C +- D/sqrt(2); with D = 0 it is the flicker-free scene (same events),
    with the render's own error sample it adds events; HDF5 attributes record the achieved noise."""
    import json

    from gevsim.emulation import prepare
    from gevsim.emulation.driver import render_noise_floor

    cfg = load_config(config(tmp_path, sensor="ideal", emulators=["dvs", "gradient"], frame_rate_hz=0.0))
    setup = prepare(cfg, cache_dir=tmp_path / "cache")
    assert setup.current_noise.shape == setup.current_basis.shape and np.abs(setup.current_noise).max() > 0
    steady = run(cfg, tmp_path / "steady.h5", setup=setup, flicker=False, noise=False)
    clean = dataclasses.replace(setup, current_noise=np.zeros_like(setup.current_noise))
    zero = run(cfg, tmp_path / "zero.h5", setup=render_noise_floor(clean, frequency_hz=500.0), noise=False)
    assert zero["counts"] == steady["counts"]
    floor = run(cfg, tmp_path / "floor.h5", setup=render_noise_floor(setup, frequency_hz=500.0), noise=False)
    assert floor["counts"]["gradient_events"] > steady["counts"]["gradient_events"]
    with EventReader(tmp_path / "floor.h5") as r:
        noise = json.loads(r.attrs["render_noise_json"])
    assert noise["spp_min"] >= 4 and noise["se_ln"]["p99"] > 0 and noise["stopped_by"] == ["fixed"]
    with pytest.raises(ValueError, match="frequency_hz"):
        render_noise_floor(setup, frequency_hz=0.0)


def test_a_failure_after_the_run_leaves_the_earlier_file(tmp_path, monkeypatch):
    """What runs after the events are written (the summary read back from the file) runs before the file
    replaces an earlier one: a crash there leaves the earlier output as it was, and no temporary file."""
    from gevsim.emulation import summary as summary_mod

    out, args = tmp_path / "x.h5", ["--cache", str(tmp_path / "c"), "-q"]
    assert main(["emulate", str(config(tmp_path)), "--out", str(out), *args]) == 0
    good = out.read_bytes()

    def crash(path, **kwargs):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(summary_mod, "summarize", crash)
    with pytest.raises(ZeroDivisionError):
        main(["emulate", str(config(tmp_path, seed=9)), "--out", str(out), *args])
    assert out.read_bytes() == good
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c", "run.toml", "x.h5"]


@pytest.mark.parametrize("emulation", [dict(duration_s=1e-9, step_s=1e-10), dict(duration_s=5e-7, step_s=1e-7)])
def test_a_time_grid_shorter_than_the_clock_tick_is_refused_up_front(tmp_path, capsys, emulation):
    out = tmp_path / "x.h5"  # (a foreign file there would be refused first: tests/io/test_output_ownership.py)
    assert main(["emulate", str(config(tmp_path, **emulation)), "--out", str(out), "--cache", str(tmp_path / "c"),
                 "-q"]) == 2
    err = capsys.readouterr().err
    assert "run.toml" in err and "emulation.duration_s" in err and "1 us" in err and err.count("\n") == 1
    assert not out.exists() and not (tmp_path / "c").exists()


def test_a_stream_at_its_bus_cap_says_so():
    """The emulate summary marks a stream whose delivered rate is the bus's (issue 35): there the count is the bus,
    not the pixels."""
    from gevsim.cli.emulate import bus_columns

    readout = {"requested": 5000, "max_rate_eps": 1e5}
    assert bus_columns(readout, 1000, pixels=100, duration_s=0.01) == (5000, 4000, "  at the bus cap (1000 ev/px/s)")
    assert bus_columns(readout, 900, pixels=100, duration_s=0.01) == (5000, 4100, "")
    assert bus_columns({}, 7, pixels=100, duration_s=0.01) == (7, 0, "")  # no readout counts: nothing lost
