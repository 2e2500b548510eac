"""The planar source in ``gevsim dataset``: its draws and setups are deterministic, the held-out photographs
stay out of training, its config errors name the key, and a small dataset holds every stream and the
ground truth."""

import json
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from gevsim.emulation.config import EmulationConfig
from gevsim.errors import ConfigError
from gevsim.experiments.dataset import generate, load_dataset_config, sequence_parameters
from gevsim.io import EventReader
from gevsim.learn.sources import SOURCES, PlanarOptions
from gevsim.learn.textures import HELD_OUT

PLANAR = SOURCES["planar"]


def write_config(folder: Path, name: str = "planar.toml", planar: dict | None = None, **changes) -> Path:
    ds = {"sequences": 2, "seed": 3, "scenes": ["planar"], "sensors": ["davis346", "dvs128"],
          "emulators": ["dvs", "gradient", "gradient_rc"], "duration_s": 0.01, "step_s": 1e-4,
          "frame_rate_hz": 500.0, "render": {"width": 32, "height": 24},
          "randomize": {"waveforms": ["pwm", "fluorescent"]}, "planar": planar or {}}
    ds.update(changes)
    path = folder / name
    path.write_text(tomli_w.dumps({"dataset": ds}))
    return path


def emulation(**changes) -> EmulationConfig:
    base = {"scene": "planar", "sensor": "davis346", "duration_s": 0.01, "step_s": 1e-4,
            "render": {"width": 32, "height": 24},
            "group_waveform": {"lamp": {"type": "pwm", "frequency_hz": 300.0, "duty": 0.5}}}
    return EmulationConfig(**{**base, **changes})


def test_draw_and_setup_are_deterministic_per_seed():
    params = [PLANAR.draw(np.random.default_rng(11), None) for _ in range(2)]
    assert params[0] == params[1] == json.loads(json.dumps(params[0]))  # JSON-ready
    assert params[0] != PLANAR.draw(np.random.default_rng(12), None)
    a, b = (PLANAR.setup(emulation(), params[0]) for _ in range(2))
    assert np.array_equal(a.current_basis, b.current_basis)
    assert a.current_basis.shape == (11, 1, 24, 32)  # 1 kHz poses over 10 ms
    assert np.array_equal(a.basis_times_s, np.arange(11) * 1e-3)


def test_texture_value_one_is_the_drawn_chip_illuminance_times_the_light_scale():
    params = PLANAR.draw(np.random.default_rng(4), None)
    setup = PLANAR.setup(emulation(light_scale=2.0), params)
    lux = setup.current_basis * setup.chip_lux_per_a[0]
    assert 0.0 < lux.max() <= 2.0 * params["illuminance_lux"] * (1 + 1e-12)
    assert setup.waveforms[0].period_s == pytest.approx(1.0 / 300.0)  # the pwm lamp, not DC
    assert setup.waveforms[0].value_range() == (0.0, 2.0)


def test_held_out_photographs_only_with_held_out():
    rng = np.random.default_rng(0)
    trained = {PLANAR.draw(rng, PlanarOptions())["texture"] for _ in range(200)}
    held = {PLANAR.draw(rng, PlanarOptions(held_out=True))["texture"] for _ in range(40)}
    assert not trained & set(HELD_OUT) and len(trained) > 10
    assert held == set(HELD_OUT)


@pytest.mark.parametrize(("planar", "key", "match"), [
    ({"textures": ["chelsea"]}, "dataset.planar.textures", "held out"),
    ({"textures": ["dead_leaf"]}, "dataset.planar.textures", "dead_leaves"),
    ({"depth": [1.0, 2.0]}, "dataset.planar.depth", "depth_m"),
    ({"depth_m": [2.0, 1.0]}, "dataset.planar.depth_m", "low <= high"),
    ({"held_out": "yes"}, "dataset.planar.held_out", "true or false"),
])
def test_planar_config_errors_name_the_key(tmp_path, planar, key, match):
    with pytest.raises(ConfigError, match=match) as err:
        load_dataset_config(write_config(tmp_path, planar=planar))
    assert err.value.key == key


def test_the_scene_does_not_depend_on_the_lamps(tmp_path):
    """A source draws from its own stream: a DC variant of a dataset shows the same planes and motions."""
    flicker = load_dataset_config(write_config(tmp_path))
    dc = load_dataset_config(write_config(tmp_path, "dc.toml", randomize={"waveforms": ["dc"]}))
    for i in range(2):
        a, b = sequence_parameters(flicker, i), sequence_parameters(dc, i)
        assert a["source"] == b["source"] and a["waveforms"] != b["waveforms"]


def test_a_planar_dataset_holds_every_stream_and_the_ground_truth(tmp_path):
    config = load_dataset_config(write_config(tmp_path))
    out = tmp_path / "out"
    summary = generate(config, out)
    assert summary["done"] == 2
    for i in range(2):
        record = json.loads((out / "shards" / f"seq_{i:05d}.json").read_text())
        assert record["parameters"]["source"] == sequence_parameters(config, i)["source"]
        with EventReader(out / "shards" / f"seq_{i:05d}.h5") as r:
            for stream in ("events", "gradient_events", "gradient_rc_events"):
                assert r.count(stream) > 0, stream
            for name in ("log_photocurrent", "log_photocurrent_no_flicker"):
                images, t_us = r.frames(name)
                assert images.shape == (6, 24, 32) and np.all(np.isfinite(images))
                assert t_us.tolist() == [0, 2000, 4000, 6000, 8000, 10000]  # 500 Hz, both ends
            flicker, steady = r.frames("log_photocurrent")[0], r.frames("log_photocurrent_no_flicker")[0]
            assert not np.array_equal(flicker, steady)  # pwm or mains lamps
    assert generate(config, out)["skipped"] == 2  # resumable: finished sequences are not redone
