"""A run's summary times every stage (issue 37, item 2): the photocurrent mix, the photoreceptor, each
emulator, the readout and the HDF5 writing included, each once, together within the run's wall time."""

from __future__ import annotations

import math
import time

from test_pinned_outputs import synthetic_setup

from gevsim.emulation import run

STAGES = ("render", "start", "ground_truth", "mix", "photoreceptor", "dvs", "gradient", "gradient_rc", "csdvs",
          "readout", "hdf5", "before_commit")
PAUSE_S = 0.2


def test_every_stage_is_timed_once_and_they_add_up_to_the_run(tmp_path):
    config, setup = synthetic_setup(poses=1)
    summary = run(config, tmp_path / "x.h5", setup=setup, before_commit=lambda tmp: time.sleep(PAUSE_S))
    stage = summary.stage_s
    assert tuple(stage) == STAGES
    assert all(math.isfinite(s) and s >= 0.0 for s in stage.values())
    # The caller's check counts to its own stage, not also to the file's writing it runs inside: a double count
    # would take the sum over the total.
    assert stage["before_commit"] >= PAUSE_S
    assert 0.9 * summary.total_s <= sum(stage.values()) <= summary.total_s
    assert summary.render_s == stage["render"] and summary.event_s == {n: stage[n] for n in STAGES[5:9]}
    assert summary.pixel_s == stage["mix"] + stage["photoreceptor"]  # the mix counts to the pixel model
    pixel_steps = summary.steps * summary.width * summary.height
    assert math.isclose(summary.pixel_steps_per_s, pixel_steps / summary.pixel_s)
