"""`gevsim train`: a tiny run learns and is deterministic, flips keep the gradient encoding consistent, and the
command's outputs and one-line errors."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.emulation import load_config, run

torch = pytest.importorskip("torch")

from gevsim.evaluation.compare import emulation_files  # noqa: E402
from gevsim.learn.model import Model  # noqa: E402
from gevsim.learn.train import TrainSettings, loss_of, train  # noqa: E402
from gevsim.learn.train_data import _flip, load_sequences  # noqa: E402

DATA = Path(__file__).parents[1] / "data"


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A dataset folder of two 32x24 sequences of a flickering card (noise seeds 1 and 2), 6 frames each."""
    tmp = tmp_path_factory.mktemp("train")
    (tmp / "data" / "shards").mkdir(parents=True)
    for seed in (1, 2):
        cfg = tmp / f"run{seed}.toml"
        cfg.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nsensor = "davis346"\nseed = {seed}\n'
                       'step_s = 2e-5\nframe_rate_hz = 1250.0\nemulators = ["dvs", "gradient", "gradient_rc"]\n'
                       '[render]\nwidth = 32\nheight = 24\n')
        run(load_config(cfg), tmp / "data" / "shards" / f"seq_{seed - 1:05d}.h5",
            cache_dir=tmp_path_factory.getbasetemp() / "learn-cache")
    return tmp / "data"


TINY = TrainSettings("dvs", batch_size=1, crop_px=(24, 32), threads=1, eval_every=10)


def _loss_on(model, sequence) -> float:
    with torch.no_grad():
        x, y = torch.from_numpy(sequence.inputs)[None], torch.from_numpy(sequence.targets)[None]
        return float(loss_of(model(x), y))


def test_a_tiny_run_lowers_the_loss_and_the_same_seed_gives_the_same_weights(dataset):
    sequences = load_sequences(emulation_files([dataset]), "dvs")
    assert [s.inputs.shape for s in sequences] == [(6, 6, 24, 32)] * 2
    result = train(sequences, replace(TINY, seed=3, steps=20, lr=3e-3))
    assert result.steps == 20 and result.n_train == result.n_validation == 1
    assert [s for s, _ in result.validation] == [10, 20]
    start = train(sequences, replace(TINY, seed=3, steps=0)).model  # the same initial weights
    before = [_loss_on(start, s) for s in sequences]  # both: the one trained on and the one held back
    after = [_loss_on(result.model, s) for s in sequences]
    assert max(after) < 0.95 * min(before), (before, after)
    a = train(sequences, replace(TINY, seed=3, steps=2)).model.state_dict()
    b = train(sequences, replace(TINY, seed=3, steps=2)).model.state_dict()
    c = train(sequences, replace(TINY, seed=4, steps=2)).model.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not torch.equal(a["head.weight"], c["head.weight"])


def test_a_flip_of_the_gradient_encoding_is_the_encoding_of_the_flipped_image():
    image = np.random.default_rng(0).normal(size=(5, 8))

    def encoding(img):  # forward differences, 0 where there is no neighbour; the DCT channel stands in as img
        gx, gy = np.zeros_like(img), np.zeros_like(img)
        gx[:, :-1], gy[:-1] = np.diff(img, axis=1), np.diff(img, axis=0)
        return np.stack([gx, gy, img])[None]

    for axis in (-1, -2):
        np.testing.assert_allclose(_flip(encoding(image), axis, "gradient"), encoding(np.flip(image, axis)))
    dvs = np.random.default_rng(1).normal(size=(1, 6, 5, 8))
    np.testing.assert_array_equal(_flip(dvs, -1, "dvs"), dvs[..., ::-1])


def test_the_command_writes_weights_provenance_and_loss_curve(dataset, tmp_path, capsys):
    out = tmp_path / "m.npz"
    args = ["train", "--events", "gradient", "--data", str(dataset), "--out", str(out), "--steps", "2",
            "--threads", "1", "-q"]
    assert main(args) == 0
    assert "gevsim: wrote" in capsys.readouterr().err
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["encoding"] == "gradient" and meta["steps"] == 2 and meta["parameters"] == 37_489
    assert len(meta["data"][str(dataset)]["shards sha256"]) == 2 and meta["seed"] == 0
    assert out.with_suffix(".png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert Model.load(out).encoding == "gradient"
    assert main(args) == 0  # an earlier training's outputs are replaced


def test_one_line_errors(dataset, tmp_path, capsys, monkeypatch):
    foreign = tmp_path / "notes.npz"
    foreign.write_bytes(b"mine")
    base = ["train", "--events", "dvs", "--steps", "1", "-q"]
    for args, text in [(["--data", str(dataset), "--out", str(foreign)], "is not a gevsim weight file"),
                       (["--data", str(dataset), "--out", str(tmp_path / "m.pt")], "an .npz file"),
                       (["--data", str(tmp_path), "--out", str(tmp_path / "m.npz")], "holds no shards"),
                       (["--data", str(tmp_path / "none"), "--out", str(tmp_path / "m.npz")], "no such file")]:
        assert main(base + args) == 2
        err = capsys.readouterr().err
        assert err.startswith("gevsim: error: ") and text in err and err.count("\n") == 1
    assert foreign.read_bytes() == b"mine" and not (tmp_path / "m.npz").exists()
    monkeypatch.setitem(sys.modules, "torch", None)  # as if PyTorch were not installed
    assert main(base + ["--data", str(dataset), "--out", str(tmp_path / "m.npz")]) == 2
    assert "pip install 'gevsim[learn]'" in capsys.readouterr().err
