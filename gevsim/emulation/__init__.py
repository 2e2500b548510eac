"""The emulation driver: scene to events, streamed to HDF5 in time chunks."""

from gevsim.emulation.config import EMULATORS, STREAMS, EmulationConfig, load_config
from gevsim.emulation.driver import prepare, run

__all__ = ["EMULATORS", "STREAMS", "EmulationConfig", "load_config", "prepare", "run"]
