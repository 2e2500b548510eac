"""Fuzz of frame and video inputs (issue 36, item 7): random small frame stacks of any pixel type, channel
layout, size, count and frame rate, saved as a user would (PNG, TIFF, palette PNG, GIF), read by the loaders and
emulated in frame mode (and set up for the sensor path) either work or raise ConfigError, never another error."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gevsim.emulation import run_frames
from gevsim.emulation.emulators import FRAME_EMULATORS
from gevsim.emulation.frame_sensor import frame_setup
from gevsim.errors import ConfigError
from gevsim.io import EventReader
from gevsim.io.frames import load_frame_folder, load_video
from gevsim.pixel import load_preset

iio = pytest.importorskip("imageio.v3")

#: Frame rates that do not divide the 20 us step (29.97, 23.976), the extremes, and bad ones.
RATES = [29.97, 30000 / 1001, 23.976, 24000 / 1001, 30.0, 1e-3, 1e6, 2e6, 0.0, -30.0, float("nan"), float("inf")]
LAYOUTS = ("gray", "rgb", "rgba", "palette")
DTYPES = ("uint8", "uint16", "float32", "float64")
#: All of frame mode's emulators (resolution compression needs even sizes), and sets without it.
EMULATOR_SETS = (FRAME_EMULATORS, ("dvs", "gradient"), ("gradient",))


@st.composite
def stacks(draw):
    layout, dtype = draw(st.sampled_from(LAYOUTS)), draw(st.sampled_from(DTYPES))
    n, h, w = draw(st.integers(1, 4)), draw(st.integers(1, 8)), draw(st.integers(1, 8))
    shape = (n, h, w) if layout in ("gray", "palette") else (n, h, w, 3 if layout == "rgb" else 4)
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    if dtype.startswith("uint"):
        top = np.iinfo(dtype).max
        stack = rng.integers(0, top, shape, endpoint=True).astype(dtype)
        if stack.ndim == 4 and draw(st.booleans()):  # gray pictures saved as colour: R = G = B
            stack[..., :3] = stack[..., :1]
    else:
        stack = rng.random(shape).astype(dtype)
        bad = draw(st.sampled_from([None] * 5 + [-0.25, 1.5, float("nan")]))  # float frames outside [0, 1]
        if bad is not None:
            stack.flat[draw(st.integers(0, stack.size - 1))] = bad
    container = draw(st.sampled_from(["folder", "gif"] if dtype == "uint8" else ["folder"]))
    fps = draw(st.sampled_from(RATES + [draw(st.floats(1e-3, 1e6))]))
    return layout, stack, container, fps, draw(st.sampled_from(EMULATOR_SETS))


def _save(folder: Path, layout: str, stack: np.ndarray, container: str) -> Path:
    from PIL import Image

    if container == "gif":
        iio.imwrite(folder / "clip.gif", stack[..., :3] if layout == "rgba" else stack, is_batch=True, loop=0,
                    duration=40)
        return folder / "clip.gif"
    for k, frame in enumerate(stack):
        name = folder / f"frame{k}"
        if layout == "palette":  # 8-bit palette PNG of whatever the values are, scaled to 8 bits
            u8 = frame if frame.dtype == np.uint8 else (np.nan_to_num(frame.astype(np.float64)) * 255 / (
                np.iinfo(frame.dtype).max if frame.dtype.kind == "u" else 1)).clip(0, 255).astype(np.uint8)
            Image.fromarray(u8, "L").convert("P").save(f"{name}.png")
        elif frame.dtype == np.uint8 or (frame.dtype == np.uint16 and frame.ndim == 2):
            iio.imwrite(f"{name}.png", frame)
        else:  # 16-bit colour and float frames: TIFF
            iio.imwrite(f"{name}.tif", frame)
    return folder


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=stacks())
def test_frame_and_video_inputs_work_or_raise_config_error(case):
    layout, stack, container, fps, emulators = case
    with tempfile.TemporaryDirectory() as tmp:
        source = _save(Path(tmp), layout, stack, container)
        try:
            frames, t = (load_video if container == "gif" else load_frame_folder)(source, fps=fps)
        except ConfigError:
            return
        assert frames.dtype == np.float64 and frames.shape[1:] == stack.shape[1:3]
        assert len(frames) == len(t) == len(stack) and np.all((frames >= 0) & (frames <= 1))
        gray = stack[..., 0] if stack.ndim == 4 else stack
        colour_gray = stack.ndim == 4 and np.all(stack[..., :3] == gray[..., None])
        if container == "folder" and (layout == "gray" or colour_gray):
            scale = np.iinfo(stack.dtype).max if stack.dtype.kind == "u" else 1  # gray values kept exactly
            np.testing.assert_array_equal(frames, gray.astype(np.float64) / scale)
        try:
            summary = run_frames(frames, t, Path(tmp) / "out.h5", source=source, emulators=emulators)
            with EventReader(Path(tmp) / "out.h5") as r:
                assert all(r.count(name) == count for name, count in summary["counts"].items())
        except ConfigError:
            pass
        try:  # the sensor path's setup: whole steps of any span (the run itself is tested elsewhere)
            setup = frame_setup(frames, t, preset=load_preset("davis346"), illuminance_lux=5.0, source=source)
            assert 0 < setup.duration_s <= t[-1] - t[0] + 1e-12
        except ConfigError:
            pass
