"""The numpy network: its size, its agreement with the PyTorch twin, and its weight file's checks."""

from __future__ import annotations

import numpy as np
import pytest

from gevsim.errors import ConfigError
from gevsim.learn.model import ARCHITECTURE, FORMAT, Model, is_model_file, parameter_count, parameter_shapes


def test_the_network_has_at_most_50k_parameters():
    # head 9 C 16 + 16, two GRUs of three 3x3 gates 32 -> 16, two residual blocks of two 3x3 16 -> 16, 1x1 16 -> 1
    per_gru, per_res = 3 * (9 * 32 * 16 + 16), 2 * (9 * 16 * 16 + 16)
    for channels in (6, 3):
        expect = 9 * channels * 16 + 16 + 2 * per_gru + 2 * per_res + 17
        assert parameter_count(channels) == expect <= 50_000
    assert parameter_count(6) == 37_921


def test_numpy_and_torch_give_the_same_frames(tmp_path):
    torch = pytest.importorskip("torch")
    from gevsim.learn.torch_model import FireNet, export

    torch.manual_seed(1)
    net = FireNet(6)
    with torch.no_grad():  # weights larger than the default init: every nonlinearity is exercised
        for p in net.parameters():
            p.uniform_(-0.3, 0.3)
    assert {k: tuple(v.shape) for k, v in net.state_dict().items()} == parameter_shapes(6)
    export(net, tmp_path / "m.npz", {"encoding": "dvs"})
    model = Model.load(tmp_path / "m.npz")
    assert model.encoding == "dvs" and model.channels == 6 and is_model_file(tmp_path / "m.npz")
    x = np.random.default_rng(2).normal(size=(4, 6, 10, 14)).astype(np.float32)
    ours = model.run(x)
    with torch.no_grad():
        theirs = net(torch.from_numpy(x)[None])[0].numpy()
    assert ours.shape == (4, 10, 14) and ours.dtype == np.float64 and np.abs(ours).max() > 0.1
    np.testing.assert_allclose(ours, theirs, atol=1e-4)
    np.testing.assert_allclose(ours.mean(axis=(1, 2)), 0, atol=1e-9)
    assert not np.allclose(ours[1], model.run(x[1:2])[0], atol=1e-3)  # recurrent: frame 1 remembers frame 0


def _weights(channels: int = 3) -> dict:
    rng = np.random.default_rng(0)
    return {k: rng.normal(size=s).astype(np.float32) for k, s in parameter_shapes(channels).items()}


def _save(path, weights, meta) -> None:
    import json

    np.savez(path, metadata=np.str_(json.dumps(meta)), **weights)


def test_inputs_of_the_wrong_width_are_refused():
    model = Model(_weights(3), {"architecture": ARCHITECTURE, "input_channels": 3, "encoding": "gradient"})
    with pytest.raises(ValueError, match=r"\(M, 3, H, W\) for the 'gradient' weights"):
        model.run(np.zeros((2, 6, 4, 4), np.float32))


def test_bad_weight_files_are_one_clear_error_naming_the_file(tmp_path):
    meta = {"format": FORMAT, "architecture": ARCHITECTURE, "input_channels": 3, "encoding": "gradient"}
    cases = {"missing.npz": None, "text.npz": b"not a zip", "nometa.npz": (_weights(), None),
             "oldarch.npz": (_weights(), {**meta, "architecture": "e2vid-0"}),
             "short.npz": ({k: v for k, v in _weights().items() if k != "pred.bias"}, meta),
             "wide.npz": (_weights(6), meta), "nan.npz": ({**_weights(), "head.bias": np.full(16, np.nan)}, meta)}
    expect = {"missing.npz": "no such weight file", "text.npz": "not a weight file", "nometa.npz": "not a gevsim",
              "oldarch.npz": "architecture 'e2vid-0'", "short.npz": "pred.bias missing or unexpected",
              "wide.npz": "corrupt weight head.weight", "nan.npz": "corrupt weight head.bias"}
    for name, content in cases.items():
        path = tmp_path / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif content is not None:
            weights, m = content
            if m is None:
                np.savez(path, **weights)
            else:
                _save(path, weights, m)
        with pytest.raises(ConfigError, match=expect[name]) as err:
            Model.load(path)
        assert str(err.value).startswith(f"{path}: ") and "\n" not in str(err.value)
        assert is_model_file(path) == (name not in ("missing.npz", "text.npz", "nometa.npz"))  # gevsim's
    _save(tmp_path / "good.npz", _weights(), meta)
    assert Model.load(tmp_path / "good.npz").channels == 3 and is_model_file(tmp_path / "good.npz")
