"""``import gevsim`` gives the names a notebook needs (docs/api.md), and stays cheap: they are imported
on first use (PEP 562), so the CLI's start does not pay for numba, Mitsuba or matplotlib."""

from __future__ import annotations

import inspect
import subprocess
import sys

import pytest

import gevsim

NAMES = [name for name in gevsim.__all__ if name != "__version__"]


def test_all_lists_every_lazy_name_and_dir_shows_them():
    assert sorted(NAMES) == sorted(gevsim._LAZY)
    assert set(gevsim.__all__) <= set(dir(gevsim))


@pytest.mark.parametrize("name", NAMES)
def test_each_public_name_resolves_to_what_the_library_defines(name):
    import importlib

    value = getattr(gevsim, name)
    assert inspect.isclass(value) or callable(value), name
    module, attribute = gevsim._LAZY[name]
    assert value is getattr(importlib.import_module(module), attribute)


def test_public_names_are_the_library_functions_behind_the_commands():
    import importlib

    from gevsim.emulation.driver import prepare, run
    from gevsim.evaluation.runner import reconstruct_file
    from gevsim.io.event_reader import EventReader
    from gevsim.io.exports import export
    from gevsim.view import view

    assert (gevsim.emulate, gevsim.prepare, gevsim.EventReader) == (run, prepare, EventReader)
    assert (gevsim.view_file, gevsim.export, gevsim.reconstruct_file) == (view, export, reconstruct_file)
    solvers = importlib.import_module("gevsim.reconstruct")  # the subpackage keeps its name beside the function
    assert gevsim.reconstruct is solvers and gevsim.reconstruct_file is reconstruct_file


def test_unknown_names_raise_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'emulat'"):
        gevsim.emulat  # noqa: B018


def test_import_gevsim_loads_no_heavy_dependency():
    code = ("import sys, gevsim\n"
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'mitsuba', 'drjit', 'matplotlib', "
            "'numpy', 'h5py'})\n"
            "print(','.join(heavy))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == ""
