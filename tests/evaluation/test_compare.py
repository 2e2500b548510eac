"""`gevsim score`: methods scored over many emulation files, with intervals over sequences (issue 38)."""

import json
import math

import numpy as np
import pytest
from scipy.stats import t as student_t

from gevsim.cli import main
from gevsim.emulation.frames import run_frames
from gevsim.errors import ConfigError
from gevsim.evaluation import reconstruct_file
from gevsim.evaluation.compare import emulation_files, paired_difference, summarize, table_markdown


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Three frame-mode sequences (a smooth pattern panned at three speeds), in a dataset-like folder."""
    tmp = tmp_path_factory.mktemp("score")
    (tmp / "ds" / "shards").mkdir(parents=True)
    yy, xx = np.mgrid[0:24, 0:32]
    out = []
    for i, speed in enumerate((0.5, 1.0, 1.5)):
        frames = np.stack([0.5 + 0.4 * np.sin(0.3 * (xx + speed * k)) * np.cos(0.25 * yy) for k in range(6)])
        path = tmp / "ds" / "shards" / f"seq_{i:05d}.h5"
        run_frames(frames, np.arange(6) / 100.0, path)
        out.append(path)
    return tmp, out


def test_the_interval_is_student_t_over_sequence_means():
    rows = [{"method": "m", "reference": "flicker", "ssim": s, "mse": 0.1 * s} for s in (0.5, 0.7, 0.9)]
    (s,) = summarize(rows)
    half = student_t.ppf(0.975, 2) * 0.2 / math.sqrt(3)  # sample sd of (0.5, 0.7, 0.9) is 0.2
    assert s["n"] == 3 and s["ssim"] == pytest.approx(0.7) and s["ssim_ci"] == pytest.approx(half)
    assert s["mse_ci"] == pytest.approx(0.1 * half)
    (one,) = summarize(rows[:1])
    assert math.isnan(one["ssim_ci"]) and "0.500 |" in table_markdown([one])  # no interval from one sequence


def test_a_paired_difference_cancels_what_the_sequences_share():
    # b is a plus a constant 0.05 on three sequences of very different difficulty: the difference is exact
    rows = [{"file": f, "method": m, "reference": "flicker", "ssim": s + (0.05 if m == "b" else 0.0)}
            for f, s in (("x", 0.2), ("y", 0.5), ("z", 0.9)) for m in ("a", "b")]
    rows.append({"file": "w", "method": "a", "reference": "flicker", "ssim": 0.4})  # only a: left out
    d = paired_difference(rows, "b", "a", "flicker")
    assert d["n"] == 3 and d["difference"] == pytest.approx(0.05) and d["ci"] == pytest.approx(0.0, abs=1e-12)
    assert paired_difference(rows, "b", "a", "no-flicker")["n"] == 0


def test_a_dataset_folder_gives_its_shards_in_order_and_a_bad_path_one_error(files, tmp_path):
    tmp, paths = files
    assert emulation_files([tmp / "ds"]) == paths
    with pytest.raises(ConfigError, match="no such file"):
        emulation_files([tmp / "missing"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match="holds no shards"):
        emulation_files([tmp_path / "empty"])


def test_cli_scores_every_sequence_as_reconstruct_does(files, tmp_path, capsys):
    tmp, paths = files
    out = tmp_path / "scores"
    assert main(["score", str(tmp / "ds"), "--method", "dct,direct", "--out", str(out), "-q"]) == 0
    assert "| dct |" in capsys.readouterr().out
    result = json.loads((out / "results.json").read_text())
    assert len(result["rows"]) == 3 * 2
    for row in result["rows"]:  # the same figure as `gevsim reconstruct` gives for that file and method
        rec, _, _ = reconstruct_file(row["file"], row["method"])
        assert row["ssim"] == pytest.approx(rec.mean_metrics()["ssim"])
    dct = next(s for s in result["summary"] if s["method"] == "dct")
    assert dct["ssim"] == pytest.approx(np.mean([r["ssim"] for r in result["rows"] if r["method"] == "dct"]))
    assert (out / "ssim.png").stat().st_size > 0 and "dct" in (out / "table.md").read_text()


def test_cli_errors_are_one_line(files, tmp_path, capsys):
    tmp, paths = files
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    cases = [(["--method", "dtc"], "did you mean"), (["--method", "dct", "--reference", "lit"], "unknown reference"),
             (["--method", "dct", "--out", str(foreign)], "did not write")]
    for extra, message in cases:
        argv = ["score", str(paths[0]), *extra]
        argv += [] if "--out" in extra else ["--out", str(tmp_path / "o")]
        assert main(argv + ["-q"]) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1
    assert (foreign / "notes.txt").read_text() == "mine"
