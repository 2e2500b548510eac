"""The shared time grid: one set of defaults, loaded from any config's main table, errors naming the key."""

import dataclasses

import numpy as np
import pytest

from gevsim._validate import FieldError
from gevsim.emulation import EmulationConfig
from gevsim.errors import ConfigError
from gevsim.experiments.dataset import DatasetConfig
from gevsim.timebase import TimeGrid


def test_defaults_are_defined_once():
    grid = TimeGrid()
    assert EmulationConfig(scene="office").time == grid == DatasetConfig(scenes=("office",)).time
    assert (grid.duration_s, grid.step_s, grid.chunk_steps, grid.frame_rate_hz) == (None, 2e-5, None, 1000.0)


def test_from_section_takes_its_keys_from_a_shared_table_and_converts():
    grid = TimeGrid.from_section({"scene": "office", "step_s": 1, "duration_s": 4}, source="a.toml", where="emulation")
    assert grid == TimeGrid(duration_s=4.0, step_s=1.0) and isinstance(grid.step_s, float)
    study = TimeGrid(duration_s=0.02, step_s=2e-5, frame_rate_hz=500.0)
    assert TimeGrid.from_section({"step_s": 1e-4}, base=study) == dataclasses.replace(study, step_s=1e-4)


@pytest.mark.parametrize(
    "table, key, fragment",
    [
        ({"step_s": 0}, "emulation.step_s", "step_s must be finite and > 0, got 0"),
        ({"chunk_steps": 2.5}, "emulation.chunk_steps", "chunk_steps must be a positive integer, got 2.5"),
        ({"frame_rate_hz": -1.0}, "emulation.frame_rate_hz", "must be finite and in [0, 1e+06], got -1.0"),
        ({"duration_s": "long"}, "emulation.duration_s", "duration_s must be a real number, got 'long'"),
        ({"duration_s": 1e-3, "step_s": 1e-3}, "emulation.step_s", "must be shorter than duration_s"),
    ],
)
def test_bad_values_name_file_and_key(table, key, fragment):
    with pytest.raises(ConfigError) as info:
        TimeGrid.from_section(table, source="a.toml", where="emulation")
    assert info.value.key == key and info.value.source == "a.toml" and fragment in str(info.value)


def test_steps_and_frame_times():
    grid = TimeGrid(step_s=2e-5, frame_rate_hz=1000.0)
    assert grid.steps(0.02) == 1000
    with pytest.raises(FieldError, match="not a whole number of steps"):
        TimeGrid(step_s=2.4e-5).steps(0.02)
    with pytest.raises(FieldError, match="shorter than the duration"):
        grid.steps(1e-5)
    np.testing.assert_allclose(grid.frame_times_s(0.003), [0.0, 0.001, 0.002, 0.003])
    assert TimeGrid(frame_rate_hz=0.0).frame_times_s(1.0).size == 0
