"""Chunks sized by memory (issue 37, item 4): ``chunk_steps`` unset takes as many steps as fit the budget (a
stated share of what the process may use, capped), an explicit one wins, and neither changes any event."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_pinned_outputs import PINS, h5_digest, synthetic_setup

from gevsim.emulation import run
from gevsim.pixel import Photoreceptor, load_preset
from gevsim.resources import (
    CHUNK_MEMORY_CAP_BYTES,
    CHUNK_MEMORY_FRACTION,
    MAX_CHUNK_STEPS,
    budget_chunk_steps,
    chunk_budget_bytes,
    step_bytes,
)

#: The synthetic run's step: 32x24 px x (8 + 4 x 4 emulators) bytes.
STEP = 32 * 24 * 24


def memory(monkeypatch, installed: int | None, ulimit: int | None = None) -> None:
    monkeypatch.setattr("gevsim._resources.physical_memory_bytes", lambda: installed)
    monkeypatch.setattr("gevsim._resources.address_space_limit_bytes", lambda: ulimit)


def test_unset_chunk_steps_follow_the_budget_and_change_no_event(tmp_path, monkeypatch):
    config, setup = synthetic_setup()  # its pin was made with chunk_steps = 37
    config = dataclasses.replace(config, chunk_steps=None)
    assert step_bytes(width=32, height=24, emulators=len(config.emulators)) == STEP
    memory(monkeypatch, int(61.5 * STEP / CHUNK_MEMORY_FRACTION))  # room for 61 steps and a half
    summary = run(config, tmp_path / "x.h5", setup=setup)
    assert summary.chunk_steps == 61 and h5_digest(tmp_path / "x.h5") == PINS["driver.h5"]
    memory(monkeypatch, 2**40)  # 256 MiB at most: the 256-step cap
    assert budget_chunk_steps(config, width=32, height=24) == MAX_CHUNK_STEPS


def test_an_explicit_chunk_steps_wins_over_the_budget(tmp_path, monkeypatch):
    config, setup = synthetic_setup(poses=1)
    memory(monkeypatch, 40 * STEP)  # the budget alone would take 2 steps; 37 steps still fit in memory
    assert budget_chunk_steps(dataclasses.replace(config, chunk_steps=None), width=32, height=24) == 2
    summary = run(config, tmp_path / "x.h5", setup=setup)
    assert summary.chunk_steps == config.chunk_steps == 37
    assert h5_digest(tmp_path / "x.h5") == PINS["driver_one_pose.h5"]


def test_the_budget_is_the_lower_of_installed_memory_and_ulimit_and_capped(monkeypatch):
    memory(monkeypatch, 2**34, ulimit=2**26)  # ulimit -v 64 MiB: 4 MiB for chunks
    assert chunk_budget_bytes() == 2**22
    memory(monkeypatch, 2**26, ulimit=None)
    assert chunk_budget_bytes() == 2**22
    memory(monkeypatch, 2**40, ulimit=2**36)
    assert chunk_budget_bytes() == CHUNK_MEMORY_CAP_BYTES
    memory(monkeypatch, None)  # the platform does not say: the cap
    assert chunk_budget_bytes() == CHUNK_MEMORY_CAP_BYTES


class Request:
    def __init__(self, chunk_steps: int | None, emulators: int):
        self.chunk_steps, self.emulators, self.step_s, self.source = chunk_steps, ("dvs",) * emulators, 2e-5, None


@settings(max_examples=60, deadline=None)
@given(installed=st.integers(1, 2**42), width=st.integers(1, 5000), height=st.integers(1, 5000),
       emulators=st.integers(1, 4), substeps=st.integers(1, 1000), explicit=st.none() | st.integers(1, 10**6))
def test_budget_chunks_fill_the_budget_within_their_bounds(installed, width, height, emulators, substeps, explicit):
    with pytest.MonkeyPatch.context() as monkeypatch:
        memory(monkeypatch, installed)
        steps = budget_chunk_steps(Request(explicit, emulators), width=width, height=height, substeps=substeps)
    if explicit is not None:
        assert steps == explicit
        return
    budget = min(installed * CHUNK_MEMORY_FRACTION, CHUNK_MEMORY_CAP_BYTES)
    per_step = width * height * substeps * (8 + 4 * emulators)
    assert 1 <= steps <= MAX_CHUNK_STEPS
    assert steps == 1 or steps * per_step <= budget  # fits, unless even one step does not
    assert steps == MAX_CHUNK_STEPS or (steps + 1) * per_step > budget  # and takes all that fits


def test_settling_in_chunks_gives_the_same_start_bit_for_bit():
    preset = load_preset("davis346")
    rng = np.random.default_rng(3)
    current = 1e-12 * (0.2 + rng.random((23, 5, 4))) * (1 + np.arange(23) % 3)[:, None, None]  # a flickering light
    dt = rng.uniform(5e-6, 4e-5, 23)
    states = []
    for source, chunk in ((current, None), (lambda a, b: current[a:b], 5), (lambda a, b: current[a:b], 1)):
        pr = Photoreceptor((5, 4), params=preset.photoreceptor, noise=preset.noise, rng=np.random.default_rng(1))
        pr.settle(source, dt, chunk_steps=chunk)
        states.append(np.concatenate([pr.v1, pr.v2, pr.settled_ln]))
    assert np.array_equal(states[0], states[1]) and np.array_equal(states[0], states[2])
