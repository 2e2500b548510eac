"""Image-quality metrics as EVREAL computes them, timestamp pairing, aggregation, bandwidth."""

import math

import numpy as np
import pytest
from skimage import data
from skimage.metrics import mean_squared_error, structural_similarity

from gevsim.metrics import (
    aggregate,
    bits_per_second,
    events_per_second,
    frame_metrics,
    lpips,
    lpips_available,
    lpips_unavailable_reason,
    mse,
    pair_by_timestamp,
    psnr,
    sequence_metrics,
    ssim,
)

EVREAL_SSIM = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1.0)


@pytest.fixture
def rng():
    return np.random.default_rng(7)


@pytest.fixture
def camera():
    return data.camera().astype(np.float64) / 255.0


def test_mse_and_ssim_equal_skimage_with_evreal_arguments_on_random_images(rng):
    gt, pred = rng.random((40, 50)), rng.random((40, 50))
    assert mse(pred, gt) == mean_squared_error(gt, pred)
    assert ssim(pred, gt) == pytest.approx(structural_similarity(gt, pred, **EVREAL_SSIM), abs=1e-15)


def test_mse_and_ssim_equal_skimage_on_a_real_image(camera, rng):
    noisy = camera + 0.05 * rng.standard_normal(camera.shape)
    clipped = np.clip(noisy, 0, 1)
    assert mse(noisy, camera) == mean_squared_error(camera, clipped)
    assert ssim(noisy, camera) == pytest.approx(structural_similarity(camera, clipped, **EVREAL_SSIM), abs=1e-15)
    assert 0.0 < ssim(noisy, camera) < 1.0


def test_values_outside_unit_range_are_clipped_before_scoring(rng):
    gt = rng.random((32, 32))
    pred = gt + rng.choice([-1.5, 1.5], size=gt.shape)  # every pixel pushed out of [0, 1]
    clipped = np.clip(pred, 0, 1)
    assert mse(pred, gt) == mean_squared_error(gt, clipped)
    assert mse(pred, gt) < mean_squared_error(gt, pred)  # clipping changes the score here
    assert ssim(pred, gt) == pytest.approx(structural_similarity(gt, clipped, **EVREAL_SSIM), abs=1e-15)
    # the reference is clipped too: a gt of 2.0 scores like a gt of 1.0
    assert mse(np.ones((16, 16)), np.full((16, 16), 2.0)) == 0.0


def test_ssim_of_identical_images_is_one(camera):
    assert ssim(camera, camera) == pytest.approx(1.0, abs=1e-12)


def test_psnr_is_ten_log10_of_inverse_mse(camera, rng):
    pred = camera + 0.1 * rng.standard_normal(camera.shape)
    assert psnr(pred, camera) == pytest.approx(10 * math.log10(1 / mse(pred, camera)), rel=1e-12)
    assert psnr(np.full((8, 8), 0.5), np.full((8, 8), 0.6)) == pytest.approx(20.0)  # MSE = 0.01
    assert psnr(camera, camera) == math.inf


def test_lpips_is_reported_unavailable_not_faked(camera):
    assert lpips_available() is False
    reason = lpips_unavailable_reason()
    assert isinstance(reason, str) and "LPIPS unavailable" in reason
    assert lpips(camera, camera) is None
    fm = frame_metrics(camera, camera)
    assert fm["lpips"] is None
    assert fm["unavailable"]["lpips"] == reason


def test_bad_frames_raise_value_error(rng):
    a = rng.random((16, 16))
    with pytest.raises(ValueError, match="equal shape"):
        mse(a, a[:-1])
    with pytest.raises(ValueError, match="2-D"):
        ssim(a[None], a[None])
    bad = a.copy()
    bad[3, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        psnr(bad, a)
    with pytest.raises(ValueError, match="at least 11x11"):
        ssim(a[:8, :8], a[:8, :8])


def test_pairing_takes_the_nearest_ground_truth_within_tolerance():
    gt_t = [0, 1000, 2000, 3000]
    pred_t = [0, 990, 1600, 2400, 2500, 5000, 2999]
    pi, gi = pair_by_timestamp(pred_t, gt_t, tolerance_us=500)
    # 1600 is 400 from 2000; 2400 is 400 from 2000; 2500 ties 2000/3000 -> earlier; 5000 dropped
    assert pi.tolist() == [0, 1, 2, 3, 4, 6]
    assert gi.tolist() == [0, 1, 2, 2, 2, 3]
    pi, gi = pair_by_timestamp(pred_t, gt_t, tolerance_us=10)
    assert pi.tolist() == [0, 1, 6] and gi.tolist() == [0, 1, 3]
    with pytest.raises(ValueError, match="non-decreasing"):
        pair_by_timestamp([0], [10, 0])


def test_sequence_metrics_average_over_paired_frames_only(rng):
    gts = rng.random((3, 20, 20))
    preds = np.stack([gts[0] + 0.1, gts[1], gts[2] - 0.2, rng.random((20, 20))])
    out = sequence_metrics(preds, [0, 1000, 2000, 9000], gts, [0, 1000, 2000], tolerance_us=100)
    assert out["n_frames"] == 3  # the frame at 9000 us has no ground truth
    frame_mse = [mse(preds[i], gts[i]) for i in range(3)]
    assert out["mse"] == pytest.approx(np.mean(frame_mse))
    # identical pair gives infinite PSNR, left out of the mean as EVREAL does
    assert out["psnr"] == pytest.approx(np.mean([psnr(preds[0], gts[0]), psnr(preds[2], gts[2])]))
    assert out["lpips"] is None and "lpips" in out["unavailable"]


def test_sequence_metrics_without_any_pair_is_an_error(rng):
    f = rng.random((1, 16, 16))
    with pytest.raises(ValueError, match="nothing to score"):
        sequence_metrics(f, [0], f, [10_000])


def test_aggregate_weights_sequences_by_frame_count():
    a = {"mse": 0.01, "ssim": 0.8, "lpips": None, "n_frames": 10, "unavailable": {"lpips": "no torch"}}
    b = {"mse": 0.04, "ssim": 0.5, "lpips": None, "n_frames": 30, "unavailable": {"lpips": "no torch"}}
    out = aggregate([(a, 10), (b, 30), ({"mse": 9.0, "ssim": 9.0, "lpips": None}, 0)])
    assert out["mse"] == pytest.approx((0.01 * 10 + 0.04 * 30) / 40)  # 0.0325, not the plain mean 0.025
    assert out["ssim"] == pytest.approx((0.8 * 10 + 0.5 * 30) / 40)
    assert out["lpips"] is None and out["unavailable"] == {"lpips": "no torch"}
    assert out["n_frames"] == 40
    with pytest.raises(ValueError, match="at least one"):
        aggregate([])
    with pytest.raises(ValueError, match="different metrics"):
        aggregate([({"mse": 1.0}, 1), ({"ssim": 1.0}, 1)])


def test_bandwidth_helpers():
    assert bits_per_second(1e6, bits_per_event=64) == 64e6
    np.testing.assert_array_equal(bits_per_second([0, 10], bits_per_event=2), [0, 20])
    assert events_per_second(500, duration_s=0.25) == 2000.0
    with pytest.raises(ValueError, match="events_per_second"):
        bits_per_second(-1.0, bits_per_event=8)
    with pytest.raises(ValueError, match="duration_s"):
        events_per_second(5, duration_s=0)
