"""The pinned outputs hold on other CPUs' code paths, emulated on this machine (issue 21).

numpy picks SIMD kernels, glibc picks FMA or SSE2 variants of libm, OpenBLAS picks a GEMM kernel
and numba compiles for the host, all at run time. Each can be steered to what another x86-64 CPU
would get:

- ``NPY_DISABLE_CPU_FEATURES`` switches numpy's AVX-512 (or AVX2 too) kernels off;
- ``GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA,...`` makes glibc choose its SSE2 libm;
- ``OPENBLAS_CORETYPE`` picks OpenBLAS's kernel;
- ``NUMBA_CPU_NAME`` makes numba compile for another CPU (with a fresh ``NUMBA_CACHE_DIR``:
  numba keys its cache by CPU, but a fresh one leaves no doubt).

The pinned-output, event-collection and CSDVS pins, and the portable functions' own pin, run
again in a subprocess under each; passing means the same SHA-256 as the native run (the pins are
hard-coded). A clone once failed 3 of these pins on an AMD EPYC with AVX2 only (FACTS.md).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PINNED = [
    "tests/test_pinned_outputs.py",
    "tests/events/test_collection.py",
    "tests/events/test_center_surround.py::test_events_are_bit_identical_to_the_per_step_kernel",
    "tests/test_portable.py::test_bits_are_pinned",
]
CPUS = {
    # An AVX2 machine without AVX-512 (AMD EPYC Zen 2/3, Intel Haswell to Comet Lake): numpy keeps
    # its X86_V3 (AVX2, FMA) kernels only.
    "avx2": {"numpy_keeps": {"X86_V3"}, "NUMBA_CPU_NAME": "haswell", "OPENBLAS_CORETYPE": "Haswell",
             "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX512F,-AVX512DQ,-AVX512BW,-AVX512VL"},
    # The x86-64 baseline: no AVX, no FMA (numpy keeps its compiled-in baseline, SSE4.2 for numpy 2.4;
    # libm and numba go down to SSE2).
    "generic": {"numpy_keeps": set(), "NUMBA_CPU_NAME": "generic", "OPENBLAS_CORETYPE": "Nehalem",
                "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-FMA4,-AVX,-AVX512F,-AVX512DQ,-AVX512BW,-AVX512VL"},
}


def cpu_environment(cpu: str) -> dict[str, str]:
    """This process's environment with the switches of ``cpu``."""
    from numpy._core._multiarray_umath import __cpu_dispatch__  # numpy's run-time dispatch targets

    spec = dict(CPUS[cpu])
    keep = spec.pop("numpy_keeps")
    env = dict(os.environ)
    env.update(spec)
    env["NPY_DISABLE_CPU_FEATURES"] = " ".join(f for f in __cpu_dispatch__ if f not in keep)
    env.pop("PYTEST_ADDOPTS", None)
    return env


@pytest.fixture(scope="module")
def numba_caches(tmp_path_factory) -> dict[str, str]:
    """One fresh numba cache per emulated CPU, shared by the tests of this module."""
    return {cpu: str(tmp_path_factory.mktemp(f"numba-{cpu}")) for cpu in CPUS}


@pytest.fixture(scope="module")
def pin_runs(numba_caches, tmp_path_factory):
    """The pinned tests under every emulated CPU, started together (each is mostly numba compiling, one
    core each, while this process waits: side by side they take the time of one); cpu -> (process, log)."""
    logs = tmp_path_factory.mktemp("pin-runs")
    runs = {}
    for cpu in sorted(CPUS):
        env = cpu_environment(cpu)
        env["NUMBA_CACHE_DIR"] = numba_caches[cpu]
        log = logs / f"{cpu}.log"
        with open(log, "w") as out:  # a file, not a pipe: a run waiting for its turn never blocks on output
            runs[cpu] = (subprocess.Popen([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *PINNED],
                                          cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT, text=True), log)
    yield runs
    for proc, _ in runs.values():
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.slow
@pytest.mark.parametrize("cpu", sorted(CPUS))
def test_pins_hold_on_another_cpu(cpu, pin_runs):
    proc, log = pin_runs[cpu]
    proc.wait(timeout=900)
    output = log.read_text()
    assert proc.returncode == 0, f"pins differ on the emulated {cpu} CPU:\n{output[-9000:]}"
    assert " passed" in output and "failed" not in output


@pytest.fixture(scope="module")
def native_run(tmp_path_factory) -> tuple[Path, Path, str]:
    """A small rendered scene emulated natively: (config, render cache, digest of the HDF5 file)."""
    from test_pinned_outputs import h5_digest

    from gevsim.cli import main

    tmp = tmp_path_factory.mktemp("rendered")
    config = tmp / "run.toml"
    config.write_text(f'[emulation]\nscene = "{ROOT / "tests" / "data" / "card.toml"}"\nsensor = "davis346"\n'
                      'seed = 4\nstep_s = 2e-5\nchunk_steps = 50\nframe_rate_hz = 1000.0\naps = true\n')
    assert main(["emulate", str(config), "--out", str(tmp / "native.h5"), "--cache", str(tmp / "cache"), "-q"]) == 0
    return config, tmp / "cache", h5_digest(tmp / "native.h5")


@pytest.mark.slow
@pytest.mark.parametrize("cpu", sorted(CPUS))
def test_a_cached_render_gives_the_same_file_on_another_cpu(cpu, native_run, numba_caches, tmp_path):
    """Renders are compiled for the host CPU (README, Reproducibility); from the same cached render
    on, an emulation (events of all four emulators, APS frames, ground truth) is the same bits."""
    from test_pinned_outputs import h5_digest

    config, cache, native = native_run
    env = cpu_environment(cpu)
    env["NUMBA_CACHE_DIR"] = numba_caches[cpu]
    out = tmp_path / f"{cpu}.h5"
    proc = subprocess.run([sys.executable, "-m", "gevsim.cli", "emulate", str(config), "--out", str(out),
                           "--cache", str(cache), "-q"], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert h5_digest(out) == native


def test_the_switches_change_code_paths():
    """The switches are not inert: where this CPU has AVX-512, numpy's exp gives other bits under
    them; where it has FMA, glibc's sin does (else this CPU already takes those paths)."""
    flags = set()
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("flags"):
            flags = set(line.split(":", 1)[1].split())
            break
    if "avx512f" not in flags and "fma" not in flags:
        pytest.skip("this CPU has neither AVX-512 nor FMA: it already takes the baseline paths")
    code = ("import numpy as np, hashlib; x = np.linspace(-30, 30, 200001); "
            "print(hashlib.sha256(np.exp(x).tobytes()).hexdigest(), hashlib.sha256(np.sin(x).tobytes()).hexdigest())")
    run = [sys.executable, "-c", code]
    native = subprocess.run(run, capture_output=True, text=True, check=True).stdout.split()
    other = subprocess.run(run, capture_output=True, text=True, check=True,
                           env=cpu_environment("generic")).stdout.split()
    if "avx512f" in flags:
        assert native[0] != other[0], "NPY_DISABLE_CPU_FEATURES did not change numpy's exp"
    if "fma" in flags:
        assert native[1] != other[1], "GLIBC_TUNABLES did not change glibc's sin"
