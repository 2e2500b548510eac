"""The chip's pixel footprint (issue 35, item 1): a window emulated at the chip's native pitch sees what the same
pixels of a full-chip run see. A 64x48 chip (davis346's pixel, a smaller array) under the card scene; its centred
32x24 window against the same pixels of the whole chip."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from gevsim.emulation import EmulationConfig, load_config, run
from gevsim.emulation.driver import prepare
from gevsim.errors import ConfigError
from gevsim.io import EventReader
from gevsim.pixel.params import ReadoutParams

DATA = Path(__file__).parents[1] / "data"
PRESET = Path(__file__).parents[2] / "noise" / "davis346.toml"


@pytest.fixture(scope="module")
def chip(tmp_path_factory) -> Path:
    """davis346's pixel on a 64x48 array."""
    text = re.sub(r"^width = 346 ", "width = 64  ", PRESET.read_text(), flags=re.M)
    text = re.sub(r"^height = 260 ", "height = 48  ", text, flags=re.M).replace('name = "davis346"', 'name = "chip64"')
    path = tmp_path_factory.mktemp("chip") / "chip64.toml"
    path.write_text(text)
    return path


def config(chip: Path, width: int, height: int, footprint: str) -> EmulationConfig:
    return EmulationConfig(scene=str(DATA / "card.toml"), sensor=str(chip), seed=1, frame_rate_hz=0.0,
                           emulators=("dvs", "gradient"), render={"width": width, "height": height, "spp": 64},
                           duration_s=0.004, footprint=footprint)


def inner_counts(path: Path, offset: tuple[int, int]) -> dict[str, int]:
    """Events of each stream in the chip's pixels 17..46 x 13..34 (the window's inside: its border pixels
    lack the outside neighbours that the gradient comparators of the full chip have)."""
    out = {}
    with EventReader(path) as r:
        for stream in ("events", "gradient_events"):
            e = r.read(stream)
            x, y = e["x"].astype(int) + offset[0], e["y"].astype(int) + offset[1]
            out[stream] = int(np.count_nonzero((x >= 17) & (x < 47) & (y >= 13) & (y < 35)))
    return out


@pytest.mark.slow
def test_a_window_at_the_chips_footprint_sees_what_the_full_chip_sees(chip, tmp_path):
    full = prepare(config(chip, 64, 48, "scene"), cache_dir=tmp_path / "cache")
    window = prepare(config(chip, 32, 24, "chip"), cache_dir=tmp_path / "cache")
    scene = prepare(config(chip, 32, 24, "scene"), cache_dir=tmp_path / "cache")
    crop = full.current_basis[..., 12:36, 16:48]
    # The same photocurrent pixel for pixel, within the renders' Monte Carlo noise (64 spp: ~2 % median).
    assert np.median(np.abs(window.current_basis / crop - 1)) < 0.04
    assert np.median(np.abs(scene.current_basis / crop - 1)) > 0.2  # the old footprint: the whole card, coarser
    counts = {}
    for name, setup, offset in (("full", full, (0, 0)), ("window", window, (16, 12))):
        unlimited = dataclasses.replace(setup, preset=dataclasses.replace(setup.preset, readout=ReadoutParams()))
        run(config(chip, setup.manifest.render.width, setup.manifest.render.height,
                   "chip" if name == "window" else "scene"), tmp_path / f"{name}.h5", setup=unlimited)
        counts[name] = inner_counts(tmp_path / f"{name}.h5", offset)
    # Pixel-level rates (no bus): DVS within 5 %, gradient within 20 % (the window draws its own fixed patterns
    # and noise, and its render's own Monte Carlo error; measured 1 % and 8 %).
    assert counts["window"]["events"] == pytest.approx(counts["full"]["events"], rel=0.05)
    assert counts["window"]["gradient_events"] == pytest.approx(counts["full"]["gradient_events"], rel=0.2)


def test_the_footprint_is_checked(chip, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(f'[emulation]\nscene = "{DATA / "card.toml"}"\nfootprint = "pixel"\n')
    with pytest.raises(ConfigError, match="footprint"):
        load_config(bad)
    with pytest.raises(ConfigError, match="does not fit"):  # a window larger than the chip
        prepare(config(chip, 128, 96, "chip"), cache_dir=tmp_path / "cache")
