"""Frame mode through the physical pixel (`gevsim emulate --frames DIR --sensor NAME --illuminance-lux L`):
the same frames in dim light make more noise events than in bright light, and the ideal pixel none."""

from __future__ import annotations

import numpy as np
import pytest

from gevsim.cli import main
from gevsim.emulation.frame_sensor import amperes_per_lux, frame_setup
from gevsim.io import EventReader
from gevsim.pixel import load_preset

iio = pytest.importorskip("imageio.v3")


@pytest.fixture(scope="module")
def still_frames(tmp_path_factory):
    """A folder of 11 identical 8-bit frames (0.1 s at 100 fps): nothing changes, so every event is noise."""
    folder = tmp_path_factory.mktemp("frames")
    y, x = np.mgrid[0:24, 0:32]
    img = (128 + 60 * np.sin(x / 5.0) * np.cos(y / 4.0)).astype(np.uint8)
    for k in range(11):
        iio.imwrite(folder / f"f{k}.png", img)
    return folder


def noise_events(folder, tmp_path, lux, sensor="davis346"):
    out = tmp_path / f"{sensor}_{lux:g}.h5"
    assert main(["emulate", "--frames", str(folder), "--fps", "100", "--sensor", sensor,
                 "--illuminance-lux", str(lux), "--emulators", "dvs", "--out", str(out), "-q"]) == 0
    with EventReader(out) as r:
        return r.count("events")


def test_dim_light_makes_more_noise_events_than_bright(still_frames, tmp_path):
    dim, bright = noise_events(still_frames, tmp_path, 0.01), noise_events(still_frames, tmp_path, 1000.0)
    # Background activity falls as the light rises (as the davis346 validation's BA-vs-lux curve; measured
    # here 1378 events at 0.01 lx, 1002 at 1 lx, 152 at 1000 lx, 24x32 px over 0.1 s).
    assert dim > 3 * max(bright, 1)
    assert noise_events(still_frames, tmp_path, 0.01, sensor="ideal") == 0  # no noise, a still scene


def test_the_frames_become_chip_light_in_proportion(still_frames):
    preset = load_preset("davis346")
    frames = np.stack([np.full((4, 5), 1.0), np.full((4, 5), 0.5)])
    setup = frame_setup(frames, np.array([0.0, 1e-3]), preset=preset, illuminance_lux=10.0, source=still_frames)
    np.testing.assert_allclose(setup.current_basis[0, 0], 10.0 * amperes_per_lux(preset))  # value 1 = 10 lux
    ratio = setup.current_basis[1, 0, 0, 0] / setup.current_basis[0, 0, 0, 0]
    assert ratio == pytest.approx(((0.5 + 0.055) / 1.055) ** 2.4)  # sRGB-decoded, not 0.5
    np.testing.assert_allclose(setup.chip_lux_per_a * setup.current_basis[0, 0, 0, 0], 10.0)


def test_sensor_and_lux_go_together(still_frames, tmp_path, capsys):
    assert main(["emulate", "--frames", str(still_frames), "--fps", "100", "--sensor", "davis346",
                 "--out", str(tmp_path / "x.h5")]) == 2
    assert "--illuminance-lux" in capsys.readouterr().err
