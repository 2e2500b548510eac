"""The shipped weights of the learned reconstruction methods (``gevsim/learn/weights``): one network per event
type, trained once by the command in the README ("Learned reconstruction"), each beside a JSON of its provenance
(the dataset config's digest, gevsim and torch versions, seed, steps, wall time, final losses)."""

from __future__ import annotations

import functools
from pathlib import Path

from gevsim.errors import ConfigError
from gevsim.learn.model import Model

__all__ = ["SHIPPED", "WEIGHTS_DIR", "shipped", "weights_digest", "weights_path"]

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"

#: Shipped weight name -> the emulator (and input encoding) it was trained on.
SHIPPED = {"e2v": "dvs", "e2v_gradient": "gradient", "e2v_gradient_rc": "gradient_rc"}


def weights_path(name: str) -> Path:
    """Where the shipped weights ``name`` live (``WEIGHTS_DIR/name.npz``)."""
    if name not in SHIPPED:
        raise ConfigError(f"no shipped weights named {name!r}; choose from {', '.join(SHIPPED)}")
    return WEIGHTS_DIR / f"{name}.npz"


@functools.lru_cache(maxsize=len(SHIPPED))
def shipped(name: str) -> Model:
    """The shipped network ``name`` (loaded once per process), checked against the encoding it must read."""
    path = weights_path(name)
    if not path.is_file():
        raise ConfigError(f"the shipped weights are missing from this installation: retrain them with `gevsim train "
                          f"--events {SHIPPED[name]} ... --out {path}` (README, Learned reconstruction)",
                          source=str(path))
    model = Model.load(path)
    if model.encoding != SHIPPED[name]:
        raise ConfigError(f"holds weights for the {model.encoding!r} encoding, not {SHIPPED[name]!r}", source=str(path))
    return model


def weights_digest(methods: object) -> dict:
    """``{"weights_sha256": {name: SHA-256}}`` of the shipped weights among ``methods`` (a study's list), or
    ``{}`` when it names none: a study's run identity holds it, so retrained weights score its runs again."""
    import hashlib

    names = [m for m in (methods if isinstance(methods, (list, tuple)) else ()) if m in SHIPPED]
    found = {m: hashlib.sha256(weights_path(m).read_bytes()).hexdigest() for m in names if weights_path(m).is_file()}
    return {"weights_sha256": found} if found else {}
