"""Variant choice: CUDA > LLVM (libLLVM >= 16) > scalar with a warning; GEVSIM_VARIANT overrides."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from gevsim.errors import ConfigError
from gevsim.render.backend import choose_variant, find_libllvm, llvm_version

ALL = ("scalar_rgb", "scalar_spectral", "llvm_ad_rgb", "llvm_ad_mono", "llvm_ad_spectral", "cuda_ad_rgb",
       "cuda_ad_mono", "cuda_ad_spectral")


@pytest.mark.parametrize(
    "name, version",
    [("libLLVM-19.so", 19), ("libLLVM-15.so.1", 15), ("libLLVM.so.21.1", 21), ("libLLVM-14.0.6.so.1", 14),
     ("/usr/lib/llvm-17/lib/libLLVM.so", 17), ("libfoo.so", None)],
)
def test_llvm_version_from_file_name(name, version):
    assert llvm_version(name) == version


def test_find_libllvm_prefers_newest_supported(tmp_path):
    for name in ("libLLVM-14.so", "libLLVM-15.so.1", "libLLVM-17.so", "libLLVM.so.20.1", "libLLVM-23.so"):
        (tmp_path / name).touch()
    assert find_libllvm([tmp_path]) == str(tmp_path / "libLLVM.so.20.1")


def test_find_libllvm_rejects_old_llvm(tmp_path):
    (tmp_path / "libLLVM-15.so").touch()
    (tmp_path / "libLLVM-14.so").touch()
    assert find_libllvm([tmp_path]) is None


def test_cuda_preferred_when_usable():
    c = choose_variant("spectral", env={}, available=ALL, cuda_ok=True, libllvm="/x/libLLVM-19.so")
    assert c.variant == "cuda_ad_spectral" and not c.fallback


def test_llvm_when_found():
    c = choose_variant("mono", env={}, available=ALL, cuda_ok=False, libllvm="/x/libLLVM-19.so")
    assert c.variant == "llvm_ad_mono" and c.libllvm == "/x/libLLVM-19.so" and not c.fallback


def test_scalar_fallback_says_how_to_get_the_fast_variant():
    c = choose_variant("rgb", env={}, available=ALL, cuda_ok=False, libllvm=None)
    assert c.variant == "scalar_rgb" and c.fallback
    assert "libllvm19" in c.reason and "DRJIT_LIBLLVM_PATH" in c.reason


def test_old_llvm_in_env_is_refused(tmp_path):
    old = tmp_path / "libLLVM-15.so"
    old.touch()
    c = choose_variant("rgb", env={"DRJIT_LIBLLVM_PATH": str(old)}, available=ALL, cuda_ok=False, libllvm=None)
    assert c.variant == "scalar_rgb" and "LLVM 15" in c.reason


def test_env_path_honoured(tmp_path):
    lib = tmp_path / "libLLVM-18.so"
    lib.touch()
    c = choose_variant("rgb", env={"DRJIT_LIBLLVM_PATH": str(lib)}, available=ALL, cuda_ok=False, libllvm=None)
    assert c.variant == "llvm_ad_rgb" and c.libllvm == str(lib)


def test_missing_env_path_falls_back():
    c = choose_variant("rgb", env={"DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM-19.so"}, available=ALL,
                       cuda_ok=False, libllvm="/x/libLLVM-19.so")
    assert c.variant == "scalar_rgb" and "does not exist" in c.reason


def test_gevsim_variant_overrides():
    c = choose_variant("rgb", env={"GEVSIM_VARIANT": "scalar_spectral"}, available=ALL, cuda_ok=True,
                       libllvm="/x/libLLVM-19.so")
    assert c.variant == "scalar_spectral" and "GEVSIM_VARIANT" in c.reason


def test_unknown_gevsim_variant_is_an_error():
    with pytest.raises(ConfigError, match="GEVSIM_VARIANT='llvm_ad_rgbb'"):
        choose_variant("rgb", env={"GEVSIM_VARIANT": "llvm_ad_rgbb"}, available=ALL, cuda_ok=False, libllvm=None)


def test_unknown_flavour_is_an_error():
    with pytest.raises(ConfigError, match="flavour"):
        choose_variant("hyperspectral", env={}, available=ALL, cuda_ok=False, libllvm=None)


def test_activate_falls_back_to_scalar_with_a_warning():
    """End to end in a fresh process: a libLLVM path that does not exist gives scalar_rgb and a warning."""
    code = (
        "import warnings\n"
        "from gevsim.render.backend import activate, ScalarFallbackWarning\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    c = activate('rgb')\n"
        "import mitsuba as mi\n"
        "print(c.variant, mi.variant(), any(issubclass(x.category, ScalarFallbackWarning) for x in w))\n"
    )
    env = {**os.environ, "DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM-19.so", "CUDA_VISIBLE_DEVICES": ""}
    env.pop("GEVSIM_VARIANT", None)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["scalar_rgb", "scalar_rgb", "True"]


def test_mono_without_scalar_mono_falls_back_to_rgb():
    available = tuple(v for v in ALL if v != "scalar_mono")
    c = choose_variant("mono", env={}, available=available, cuda_ok=False, libllvm=None)
    assert c.variant == "scalar_rgb" and c.fallback and "no scalar_mono" in c.reason


def test_activate_variant_sets_exactly_that_variant_or_says_why_not():
    """In a fresh process without libLLVM: scalar_rgb is set, llvm_ad_rgb and unknown names are ConfigErrors."""
    code = (
        "from gevsim.errors import ConfigError\n"
        "from gevsim.render.backend import activate_variant\n"
        "import mitsuba as mi\n"
        "print(activate_variant('scalar_rgb').variant, mi.variant())\n"
        "for name in ('llvm_ad_rgb', 'hyper_rgb'):\n"
        "    try:\n"
        "        activate_variant(name)\n"
        "    except ConfigError as exc:\n"
        "        print(str(exc).replace(' ', '_'))\n"
    )
    env = {**os.environ, "DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM-19.so", "CUDA_VISIBLE_DEVICES": ""}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split()
    assert lines[:2] == ["scalar_rgb", "scalar_rgb"]
    assert "cannot_run_llvm_ad_rgb:_drjit_could_not_load_libLLVM" in lines[2]
    assert "'hyper_rgb'_is_not_a_variant" in lines[3]


@pytest.mark.slow
def test_a_test_that_needs_the_jit_is_skipped_not_run_on_the_scalar_fallback():
    """The conftest's variant fixtures skip where LLVM cannot load, instead of testing scalar_rgb."""
    env = {**os.environ, "DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM-19.so", "CUDA_VISIBLE_DEVICES": ""}
    env.pop("GEVSIM_VARIANT", None)
    tests = Path(__file__).parents[1]
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rs",
                          str(tests / "render" / "test_integrator.py"), "-k", "reproducible or falls_back"],
                         env=env, capture_output=True, text=True, timeout=300, cwd=tests.parent)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "1 passed, 3 skipped" in out.stdout  # scalar_rgb runs; llvm_ad_rgb, cuda_ad_rgb, the JIT test skip
    assert "drjit could not load libLLVM" in out.stdout
