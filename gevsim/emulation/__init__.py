"""Emulation: a scene to events, streamed to HDF5 in time chunks (the driver), or a frame
sequence to events (frame mode)."""

from gevsim.emulation.config import EmulationConfig, load_config
from gevsim.emulation.driver import prepare, run
from gevsim.emulation.emulators import EMULATORS, STREAMS
from gevsim.emulation.frames import emulate_frames, run_frames
from gevsim.emulation.summary import RunSummary, StreamStats, summarize

__all__ = ["EMULATORS", "STREAMS", "EmulationConfig", "RunSummary", "StreamStats", "emulate_frames", "load_config",
           "prepare", "run", "run_frames", "summarize"]
