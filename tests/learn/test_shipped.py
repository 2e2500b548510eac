"""The shipped weights (issue 38): they load, match their provenance, read the encoding they were trained on, and
give pinned scores on a small held-out sequence (a held-out photograph, panned, in the paper's frame mode)."""

import hashlib
import json

import numpy as np
import pytest

from gevsim.emulation.frames import run_frames
from gevsim.evaluation import reconstruct_file
from gevsim.learn.model import parameter_count
from gevsim.learn.shipped import SHIPPED, shipped, weights_path
from gevsim.learn.textures import texture

#: SSIM of each learned method on the sequence below, as this gevsim computes it on any CPU (portable arithmetic).
PINNED_SSIM = {"e2v": 0.07734607093117167, "e2v_gradient": 0.5638406227821998, "e2v_gradient_rc": 0.652555608695252}


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_weights_load_and_match_their_provenance(name):
    model = shipped(name)
    assert model.encoding == SHIPPED[name]
    provenance = json.loads(weights_path(name).with_suffix(".json").read_text())
    assert provenance["encoding"] == SHIPPED[name]
    assert provenance["parameters"] == parameter_count(model.channels) <= 50_000
    assert provenance["steps"] > 0 and np.isfinite(provenance["final_train_loss"])
    assert provenance["weights_sha256"] == hashlib.sha256(weights_path(name).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def held_out(tmp_path_factory):
    """chelsea (never in training), a 48x36 window panned 2 px per frame, 6 frames at 100 Hz."""
    photo = texture("chelsea")
    frames = np.stack([photo[100 + 2 * k:136 + 2 * k, 150 + 2 * k:198 + 2 * k] for k in range(6)])
    path = tmp_path_factory.mktemp("heldout") / "chelsea.h5"
    run_frames(np.round(frames * 255) / 255, np.arange(6) / 100.0, path)
    return path


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_weights_give_the_pinned_ssim_on_a_held_out_photograph(held_out, name):
    rec, gt, _ = reconstruct_file(held_out, name)
    assert rec.frames.shape == gt.shape and np.all(np.isfinite(rec.frames))
    assert rec.mean_metrics()["ssim"] == pytest.approx(PINNED_SSIM[name], abs=1e-9)


def test_a_study_scores_its_runs_again_after_the_weights_change_and_only_then(tmp_path, monkeypatch):
    import shutil

    from gevsim.experiments import study as study_mod
    from gevsim.learn import shipped as shipped_mod

    def run_ids(methods: str) -> str:
        path = tmp_path / f"{methods}.toml"
        path.write_text(f'[study]\nname = "t"\nscene = "office"\nsensor = "davis346"\nemulators = ["dvs", "gradient"]\n'
                        f'flicker_group = "ceiling"\nmethods = [{methods}]\n[sweep]\nwaveform = ["dc"]\n')
        study = study_mod.load_study(path)
        return study_mod.run_id(study, study.runs()[0])

    learned, classical = run_ids('"dct", "e2v"'), run_ids('"dct"')
    copy = tmp_path / "weights"
    shutil.copytree(shipped_mod.WEIGHTS_DIR, copy)
    monkeypatch.setattr(shipped_mod, "WEIGHTS_DIR", copy)
    assert run_ids('"dct", "e2v"') == learned  # the same bytes: the same run
    data = bytearray((copy / "e2v.npz").read_bytes())
    data[-1] ^= 1  # retrained weights (a bit of them)
    (copy / "e2v.npz").write_bytes(bytes(data))
    assert run_ids('"dct", "e2v"') != learned and run_ids('"dct"') == classical
