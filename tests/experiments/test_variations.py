"""Runs around a study's headline (issue 35): the assumed numbers at the ends of their ranges, joint draws,
trade-off settings; the answer's length; where gradient events win."""

import json
import re
from pathlib import Path

import pytest

from gevsim.cli import main
from gevsim.errors import ConfigError
from gevsim.experiments.answer import MAX_WORDS, answer, words
from gevsim.experiments.study import load_study
from gevsim.experiments.variation_report import Point, wins
from gevsim.metrics.attribution import Interval
from gevsim.pixel import load_preset

DATA = Path(__file__).parents[1] / "data"

AROUND = """
[report]
x = "waveform"
headline = { waveform = "sinusoid" }
[sensitivity]
assumed = ["noise.dc_offset_v"]
joint = 1
repeats = 2
[tradeoff]
settings = [{ hysteresis_ln = 0.02 }]
repeats = 2
"""


def write(tmp_path, around=AROUND, sweep='waveform = ["sinusoid"]'):
    path = tmp_path / "study.toml"
    path.write_text(f"""
[study]
name = "around"
scene = "{DATA / 'card.toml'}"
sensor = "davis346"
emulators = ["dvs", "gradient"]
flicker_group = "lamp"
duration_s = 0.003
step_s = 2e-5
frame_rate_hz = 1000.0
seed = 5
repeats = 2
methods = ["dct", "direct"]
[study.render]
width = 24
height = 18
spp = 2
[sweep]
{sweep}
modulation = [0.8]
frequency_hz = [1000.0]
{around}""")
    return path


def test_the_runs_around_the_headline(tmp_path):
    study = load_study(write(tmp_path))
    entry = load_preset("davis346").assumed["noise.dc_offset_v"]
    runs = study.variations()
    assert [(v.kind, v.end) for v in runs] == [("sensitivity", "low"), ("sensitivity", "high"), ("joint", ""),
                                               ("tradeoff", "")]
    assert [v.params["assumed"]["noise.dc_offset_v"] for v in runs[:2]] == [entry.low, entry.high]
    drawn = runs[2].params["assumed"]["noise.dc_offset_v"]
    assert entry.low <= drawn <= entry.high
    assert load_study(write(tmp_path)).variations()[2].params == runs[2].params  # drawn from the study's seed
    assert runs[3].params == {**study.headline, "hysteresis_ln": 0.02}


@pytest.mark.parametrize("around, key", [
    ('[report]\nx = "waveform"\nheadline = { waveform = "dc" }\n', "report.headline"),
    ('[report]\nx = "waveform"\nheadline = { wavefrom = "sinusoid" }\n', "report.headline"),
    ('[sensitivity]\nassumed = ["noise.dc_ofset_v"]\n', r"sensitivity.assumed\[0\]"),
    ('[sensitivity]\njoint = -1\n', "sensitivity.joint"),
    ('[tradeoff]\nsettings = [{ hysteresis_ln = 0.5 }]\n', r"tradeoff.settings\[0\]"),  # above the 0.05 threshold
    ('[tradeoff]\nsettings = [{ waveform = "candle" }]\n', r"tradeoff.settings\[0\]"),
])
def test_bad_tables_name_their_key(tmp_path, around, key):
    with pytest.raises(ConfigError, match=key):
        load_study(write(tmp_path, around=around))


def test_a_study_around_its_headline_end_to_end(tmp_path):
    out = tmp_path / "out"
    assert main(["study", str(write(tmp_path)), "--out", str(out), "--cache", str(tmp_path / "c"), "-q"]) == 0
    head = json.loads((out / "results.json").read_text())[0]
    around = json.loads((out / "variations.json").read_text())
    assert [r["variation"] for r in around] == ["sensitivity", "sensitivity", "joint", "tradeoff"]
    # Common random numbers: dc_offset_v and the gradient's hysteresis act on gradients only, so with the
    # headline's seeds DVS makes exactly the headline's events in every run around it.
    for row in around:
        assert row["dvs_pixel_events_per_pixel_s"] == head["dvs_pixel_events_per_pixel_s"]
        assert row["repeats"] == 2 and row["seeds"] == head["seeds"]
    assert around[3]["gradient_pixel_events_per_pixel_s"] != head["gradient_pixel_events_per_pixel_s"]
    # A sensitivity job emulates the run and its flicker-free and ideal counterfactuals only.
    record = json.loads(next((out / "runs" / around[0]["id"]).glob("r0.json")).read_text())
    assert set(record["counts"]) == {"run", "no_flicker", "ideal"} and record["metrics"] == {}
    report = (out / "report.md").read_text()
    for name in ("tornado.png", "tradeoff.png"):
        assert f"]({name})" in report and (out / name).is_file()
    assert "## How far the answer moves with what was assumed" in report and "`noise.dc_offset_v`" in report
    text = report.split("## Answer", 1)[1].split("\n\n")[1]
    assert len(re.findall(r"[.!?](?:\s|$)", text)) <= 3 and len(text.split()) <= MAX_WORDS


def _iv(value, half=1.0):
    return Interval(value, value - half, value + half, 0.95, 4, "t")


def _point(e, setting, flicker, noise, made):
    return Point(e, setting, _iv(flicker), _iv(noise), made, made, float("nan"), "-", False)


def test_gradient_wins_only_on_both_counts_at_no_more_bandwidth():
    dvs = _point("dvs", "a", flicker=100, noise=20, made=130)
    assert wins([dvs, _point("gradient", "b", flicker=10, noise=10, made=30)])
    assert not wins([dvs, _point("gradient", "b", flicker=10, noise=300, made=320)])  # noisier
    assert not wins([dvs, _point("gradient", "b", flicker=10, noise=19.5, made=30)])  # intervals overlap
    assert not wins([dvs, _point("gradient", "b", flicker=10, noise=10, made=200)])  # more bandwidth


def _row(**kw):
    row = {"scene": "office", "flicker_group": "ceiling", "flicker_frequency_hz": 500.0, "repeats": 4, "pixels": 6912,
           "bus_cap_per_pixel_s": 133.0, "dvs_bus_limited": True, "gradient_bus_limited": True}
    for key, (v, lo, hi) in kw.items():
        row.update({key: v, f"{key}_low": lo, f"{key}_high": hi})
    return row


def test_the_answer_is_three_sentences_and_says_the_bus_is_full_not_a_rate():
    row = _row(dvs_pixel_flicker_per_pixel_s=(1380.0, 1370.0, 1390.0),
               gradient_pixel_flicker_per_pixel_s=(30.4, 28.5, 32.3),
               dvs_pixel_noise_per_pixel_s=(20.0, 19.0, 21.0), gradient_pixel_noise_per_pixel_s=(600.0, 590.0, 610.0),
               pixel_flicker_rejection_ratio=(45.3, 42.5, 48.5), dvs_flicker_per_pixel_s=(132.0, 132.0, 132.0),
               gradient_flicker_per_pixel_s=(0.0, -0.01, 0.01))

    class Study:
        headline = {"scene": "office"}
        base = {"scene": "office", "render": {"width": 96, "height": 72}, "footprint": "chip"}

    sentences = answer([row], Study, [], "DAVIS346")
    assert len(sentences) <= 3 and words(sentences) <= MAX_WORDS
    text = " ".join(sentences)
    assert "45.3 [42.5, 48.5]" in text and "96x72 window" in text
    assert "DVS with flicker and gradient with noise fill it" in text  # 1380 > 133 by flicker; 600 > 133 by noise
    assert "132" not in text  # the delivered difference of two full buses is no flicker rate


def test_a_swept_window_sets_the_rendered_size(tmp_path):
    from gevsim.experiments.study import run_config

    study = load_study(write(tmp_path, around="", sweep='waveform = ["sinusoid"]\nwindow = [[24, 18], [32, 24]]'))
    assert [(run_config(study, p).render["width"], run_config(study, p).render["height"]) for p in study.runs()] \
        == [(24, 18), (32, 24)]
    with pytest.raises(ConfigError, match="sweep.window"):
        load_study(write(tmp_path, around="", sweep='waveform = ["sinusoid"]\nwindow = [[24, 0]]'))
