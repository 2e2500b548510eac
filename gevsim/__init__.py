"""gevsim: a physically based event-camera emulator.

Mitsuba 3 renders HDR irradiance of scenes with flickering lamps; a
logarithmic photoreceptor and noise model turns it into pixel voltages that
drive brightness (DVS) and gradient event emulators (Lehtonen et al.).

The names a notebook needs are here (docs/api.md)::

    import gevsim
    config = gevsim.EmulationConfig(scene="office", duration_s=0.01)   # or gevsim.load_config("my.toml")
    gevsim.emulate(config, "office.h5")
    with gevsim.EventReader("office.h5") as r:
        events = r.read("events")

They are imported on first use (PEP 562), so ``import gevsim`` stays cheap: the
CLI imports it before it knows what it will run.
"""

from __future__ import annotations

import importlib
import os

#: How numba's OpenMP threads wait at the end of a parallel loop (docs/api.md, "Threads"): GNU OpenMP, numba's "omp"
#: threading layer here, spins ~300,000 times (milliseconds) by default, and beside other work its spinning
#: threads took the cores the others needed: 2 threads ran 5.3x slower than 1 on a loaded machine (issue 37).
#: PASSIVE sleeps at once. libgomp reads it when it loads (numba's first parallel call), so it is set at
#: ``import gevsim``, never over a value the user set; child processes inherit it.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads the name)

__version__ = "0.1.0"

#: Public name -> (module, attribute), imported when first asked for. ``gevsim.view`` and
#: ``gevsim.reconstruct`` are modules (the importer sets them on this package when they load), so the
#: functions behind ``gevsim view`` and ``gevsim reconstruct`` are ``view_file`` and ``reconstruct_file``.
_LAZY: dict[str, tuple[str, str]] = {
    "EmulationConfig": ("gevsim.emulation.config", "EmulationConfig"),
    "load_config": ("gevsim.emulation.config", "load_config"),
    "load_preset": ("gevsim.pixel.presets", "load_preset"),
    "prepare": ("gevsim.emulation.driver", "prepare"),
    "emulate": ("gevsim.emulation.driver", "run"),
    "EventReader": ("gevsim.io.event_reader", "EventReader"),
    "view_file": ("gevsim.view", "view"),
    "export": ("gevsim.io.exports", "export"),
    "reconstruct_file": ("gevsim.evaluation.runner", "reconstruct_file"),
}

__all__ = ["EmulationConfig", "EventReader", "__version__", "emulate", "export", "load_config", "load_preset",
           "prepare", "reconstruct_file", "view_file"]  # tests/test_public_api.py: these and _LAZY agree

if TYPE_CHECKING:  # what static tools see; at run time __getattr__ imports them
    from typing import Any

    from gevsim.emulation.config import EmulationConfig, load_config
    from gevsim.emulation.driver import prepare
    from gevsim.emulation.driver import run as emulate
    from gevsim.evaluation.runner import reconstruct_file
    from gevsim.io.event_reader import EventReader
    from gevsim.io.exports import export
    from gevsim.pixel.presets import load_preset
    from gevsim.view import view as view_file


def __getattr__(name: str) -> Any:
    """Import a public name on first use (then it is a module attribute like any other)."""
    if name not in _LAZY:
        raise AttributeError(f"module 'gevsim' has no attribute {name!r}")
    module, attribute = _LAZY[name]
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
