"""`gevsim reconstruct` on a tiny emulation: outputs, scores, protocol, errors."""

import json
from pathlib import Path

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.emulation import load_config, run
from gevsim.evaluation import reconstruct_file
from gevsim.tonemap import ToneMap

DATA = Path(__file__).parents[1] / "data"


@pytest.fixture(scope="module")
def emulation(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("emu")
    cfg = tmp / "run.toml"
    cfg.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nsensor = "davis346"\nseed = 2\nstep_s = 2e-5\n'
                   'frame_rate_hz = 1500.0\naps = true\naps_exposure_s = 5e-4\n'
                   '[render]\nwidth = 48\nheight = 36\n')
    run(load_config(cfg), tmp / "run.h5", cache_dir=tmp / "cache", noise=False)
    return tmp / "run.h5"


def test_tone_map_is_fixed_by_the_ground_truth():
    gt = np.linspace(-30, -20, 1000).reshape(10, 10, 10)
    tone = ToneMap.from_ground_truth(gt)
    assert tone(np.array([tone.low, tone.high, tone.low - 5]))[:].tolist() == [0.0, 1.0, 0.0]
    with pytest.raises(ValueError, match="low < high"):
        ToneMap(1.0, 1.0)


def test_gradient_reconstruction_of_a_static_card_scores_well(emulation):
    rec, gt, tone = reconstruct_file(emulation, "dct")
    assert rec.frames.shape == gt.shape
    # Each reconstruction carries the ground-truth mean (the papers' protocol).
    np.testing.assert_allclose(rec.frames.mean(axis=(1, 2)), gt.mean(axis=(1, 2)))
    assert rec.mean_metrics()["ssim"] > 0.5
    sor, _, _ = reconstruct_file(emulation, "sor")
    assert abs(sor.mean_metrics()["ssim"] - rec.mean_metrics()["ssim"]) < 0.2


def test_photodiode_level_is_the_log_of_the_mean_irradiance(emulation):
    rec, gt, _ = reconstruct_file(emulation, "dct", mean="photodiode")
    expect = np.log(np.exp(gt).mean(axis=(1, 2)))
    np.testing.assert_allclose(rec.frames.mean(axis=(1, 2)), expect)


def test_cli_writes_frames_metrics_and_side_by_side(emulation, tmp_path, capsys):
    out = tmp_path / "rec"
    assert main(["reconstruct", str(emulation), "--method", "dct,sor_rc", "--method", "direct",
                 "--method", "complementary", "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert "dct" in table and "complementary" in table
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics["summary"]["methods"]) == {"dct", "sor_rc", "direct", "complementary"}
    rows = (out / "metrics.csv").read_text().splitlines()
    assert rows[0] == "method,frame,t_us,mse,ssim,psnr" and len(rows) == 1 + 4 * metrics["summary"]["frames"]
    assert (out / "side_by_side.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(list((out / "frames" / "dct").glob("*.png"))) == metrics["summary"]["frames"]
    from gevsim.io import EventReader

    with EventReader(emulation) as r:
        n_gradient, duration = len(r.read("gradient_events")), r.t_end_us / 1e6
    band = metrics["summary"]["bandwidth"]
    assert band["dct"]["stream"] == "gradient_events" and band["sor_rc"]["stream"] == "gradient_rc_events"
    assert band["dct"]["events_per_s"] == pytest.approx(n_gradient / duration)
    assert band["dct"]["bits_per_s"] == pytest.approx(32 * n_gradient / duration)


@pytest.mark.parametrize("args, text", [(["--method", "dtc"], "did you mean 'dct'"),
                                        (["--method", "dct", "--mean", "median"], "unknown mean")])
def test_bad_arguments(emulation, tmp_path, capsys, args, text):
    assert main(["reconstruct", str(emulation), "--out", str(tmp_path / "r")] + args) == 2
    assert text in capsys.readouterr().err and not (tmp_path / "r").exists()


def test_no_flicker_reference_is_the_scene_with_lamps_at_their_mean(emulation):
    from gevsim.io import EventReader

    rec, gt, _ = reconstruct_file(emulation, "dct", reference="no-flicker")
    with EventReader(emulation) as r:
        flicker = r.frames("log_photocurrent")[0]
        steady = r.frames("log_photocurrent_no_flicker")[0]
    np.testing.assert_allclose(gt, steady)
    # The steady reference differs from the instantaneous one by the lamp's waveform only: one
    # lamp lights everything in the card scene, so where the photocurrent dwarfs the dark
    # current the difference is one ln offset per frame.
    bright = steady[0] > np.median(steady[0])
    offset = (flicker - steady)[:, bright]
    assert np.all(offset.std(axis=1) < 0.01) and offset.mean(axis=1).std() > 0.1
    with pytest.raises(ValueError, match="unknown reference"):
        reconstruct_file(emulation, "dct", reference="steady")


def test_brightness_reconstruction_uses_the_sensors_contrast_step(emulation):
    from gevsim.io import EventReader
    from gevsim.pixel import load_preset

    with EventReader(emulation) as r:
        stored = r.array("/thresholds/dvs")
    events = load_preset("davis346").events
    np.testing.assert_allclose(stored, [events.threshold_on_ln, events.threshold_off_ln])
    a, _, _ = reconstruct_file(emulation, "direct")  # the stored step
    b, _, _ = reconstruct_file(emulation, "direct", contrast_ln=2 * events.threshold_on_ln)
    # Before mean matching, doubling the step doubles every frame's deviation from its mean.
    da = a.frames - a.frames.mean(axis=(1, 2), keepdims=True)
    db = b.frames - b.frames.mean(axis=(1, 2), keepdims=True)
    np.testing.assert_allclose(db, 2 * da, atol=1e-9)


@pytest.mark.parametrize("method", ["dct", "sor_rc", "direct", "high_pass", "complementary"])
def test_methods_read_events_in_bounded_windows_with_the_same_frames(emulation, monkeypatch, method):
    """Events are read window by window (each read at most WINDOW_EVENTS events, or one
    millisecond's), and the windows do not change a single bit of the frames."""
    from gevsim.evaluation.methods import check_method
    from gevsim.io import EventReader

    whole, _, _ = reconstruct_file(emulation, method)
    with EventReader(emulation) as r:
        stream = check_method(method).stream
        per_ms = int(np.diff(r.ms_to_idx(stream)).max())
        total = r.count(stream)
        assert total > 2 * max(per_ms, 8)  # the bound is well below the whole stream
    sizes = []
    read = EventReader.read

    def spy(self, *args, **kwargs):
        out = read(self, *args, **kwargs)
        sizes.append(len(out))
        return out

    monkeypatch.setattr(EventReader, "read", spy)
    monkeypatch.setattr("gevsim.io.event_reader.WINDOW_EVENTS", 8)
    windowed, _, _ = reconstruct_file(emulation, method)
    assert max(sizes) <= max(per_ms, 8) < total and len(sizes) > 4
    np.testing.assert_array_equal(windowed.frames, whole.frames)
    assert windowed.metrics == whole.metrics
