"""Input encodings of the learned reconstruction: shapes, and each channel against what it stands for."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gevsim.emulation import load_config, run
from gevsim.evaluation.runner import ground_truth
from gevsim.evaluation.streams import contrast_steps, decoding_inputs
from gevsim.events import decode
from gevsim.io import EventReader
from gevsim.learn.encode import BINS, ENCODINGS, encode, voxel_grid
from gevsim.reconstruct.gradient import GradientReconstructor, quantized_gradients

DATA = Path(__file__).parents[1] / "data"


@pytest.fixture(scope="module")
def emulation(tmp_path_factory):
    """A flickering card, 32x24 px, 4 ms, ground truth every 400 us, with all three streams."""
    tmp = tmp_path_factory.mktemp("encode")
    cfg = tmp / "run.toml"
    cfg.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nsensor = "davis346"\nseed = 2\nstep_s = 2e-5\n'
                   'frame_rate_hz = 2500.0\nemulators = ["dvs", "gradient", "gradient_rc"]\n'
                   '[render]\nwidth = 32\nheight = 24\n')
    run(load_config(cfg), tmp / "run.h5", cache_dir=tmp_path_factory.getbasetemp() / "learn-cache")
    return tmp / "run.h5"


def test_the_voxel_grid_splits_an_event_between_its_two_nearest_bins():
    # t* = (B - 1)(t - t0)/(t1 - t0): 150 us of 400 is t* = 1.5; t = t1 is the last bin; t = t0 the first.
    grid = voxel_grid(np.array([1, 0, 2]), np.array([0, 1, 1]), np.array([150, 400, 0]), np.array([2.0, -1.0, 0.5]),
                      t0_us=0, t1_us=400, shape=(2, 3))
    assert grid.shape == (BINS, 2, 3)
    np.testing.assert_allclose(grid[:, 0, 1], [0, 1.0, 1.0, 0, 0])
    np.testing.assert_allclose(grid[:, 1, 0], [0, 0, 0, 0, -1.0])
    np.testing.assert_allclose(grid[:, 1, 2], [0.5, 0, 0, 0, 0])
    assert np.count_nonzero(grid) == 4


def test_dvs_voxels_sum_to_each_windows_signed_contrast_and_the_last_channel_integrates(emulation):
    with EventReader(emulation) as r:
        gt, t_us, _ = ground_truth(r)
        x = encode(r, "dvs", t_us, gt.shape[1:])
        events, (on, off) = r.read("events"), contrast_steps(r, None)
    assert x.shape == (len(t_us), ENCODINGS["dvs"].channels, 24, 32) == (len(t_us), 6, 24, 32) and x.dtype == np.float32
    assert len(events) > 50
    total = np.zeros((24, 32))
    for k, t in enumerate(t_us):
        inside = events[(events["t"] <= t) & ((events["t"] > t_us[k - 1]) if k else True)]
        window = np.zeros((24, 32))
        np.add.at(window, (inside["y"], inside["x"]), np.where(inside["p"], on, -off))
        np.testing.assert_allclose(x[k, :BINS].sum(axis=0), window, atol=1e-5)
        total += window
        np.testing.assert_allclose(x[k, BINS], total - total.mean(), atol=1e-5)


@pytest.mark.parametrize("emulator, stream, rc", [("gradient", "gradient_events", False),
                                                  ("gradient_rc", "gradient_rc_events", True)])
def test_gradient_channels_are_the_decoded_state_times_the_thresholds_and_its_dct(emulation, emulator, stream, rc):
    with EventReader(emulation) as r:
        gt, t_us, _ = ground_truth(r)
        x = encode(r, emulator, t_us, gt.shape[1:], c=3.6)
        theta, initial = decoding_inputs(r, emulator, gt.shape[1:])
        events = r.read(stream)
    assert x.shape == (len(t_us), 3, 24, 32) and len(events) > 50
    for k in (0, len(t_us) // 2, len(t_us) - 1):
        state = decode(events, initial, t_us=int(t_us[k]))
        gx, gy = quantized_gradients(state, theta, rc=rc)
        np.testing.assert_allclose(x[k, 0], gx, atol=1e-6)
        np.testing.assert_allclose(x[k, 1], gy, atol=1e-6)
        poisson = GradientReconstructor((24, 32), theta, rc=rc, method="dct", c=3.6).frame(state)
        np.testing.assert_allclose(x[k, 2], poisson - poisson.mean(), atol=1e-5)
    assert abs(float(x[-1, 2].mean())) < 1e-5 and np.any(x[-1, :2] != 0)


def test_an_unknown_encoding_is_refused(emulation):
    with EventReader(emulation) as r, pytest.raises(ValueError, match="unknown encoding 'csdvs'"):
        encode(r, "csdvs", [0], (24, 32))
