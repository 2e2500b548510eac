"""Peak memory of `gevsim reconstruct` on a 100 ms, 346x260 emulation with the davis346 sensor.

Usage: python benchmarks/reconstruct_memory.py [--duration-s 0.1] [--method direct --method dct] [--keep DIR]

Emulates a fixed photocurrent (a scikit-image photograph under a 500 Hz PWM and a 300 Hz
sinusoidal lamp, no rendering; DVS and gradient events, ground-truth frames at 1 kHz),
then runs ``gevsim reconstruct FILE --method M`` in a child process per method and
prints its peak resident memory (VmHWM, Linux) and wall time, with the events in the file.
Importing gevsim and its dependencies alone takes ~220 MiB here.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
import types
from pathlib import Path

import numpy as np
from skimage import data
from skimage.transform import resize

from gevsim.emulation import EmulationConfig, run
from gevsim.emulation.driver import Setup
from gevsim.illumination import from_spec
from gevsim.pixel import load_preset
from gevsim.render import load, override

#: The child: `gevsim reconstruct ARGS`, then its own peak resident memory (KiB, VmHWM of Linux's
#: /proc/self/status; ru_maxrss would include the parent's peak, inherited through fork) on the last line.
CHILD = ("import re, sys; from gevsim.cli import main; rc = main(sys.argv[1:]); "
         "print(re.search(r'VmHWM:\\s*(\\d+)', open('/proc/self/status').read()).group(1)); sys.exit(rc)")
CARD = Path(__file__).parents[1] / "tests" / "data" / "card.toml"


def emulate(path: Path, duration_s: float) -> dict:
    h, w = 260, 346
    manifest = override(load(CARD), width=w, height=h)
    img = resize(data.camera().astype(float) / 255, (h, w)) * 0.9 + 0.05
    basis = np.stack([np.stack([2e-11 * img, 1e-11 * img[:, ::-1]])])
    waveforms = (from_spec({"type": "pwm", "frequency_hz": 500.0, "duty": 0.4}),
                 from_spec({"type": "sinusoid", "frequency_hz": 300.0, "modulation": 0.6}))
    config = EmulationConfig(scene=str(CARD), sensor="davis346", seed=7, duration_s=duration_s, step_s=1e-5,
                             frame_rate_hz=1000.0, emulators=("dvs", "gradient"), render={"width": w, "height": h})
    setup = Setup(manifest=manifest, preset=load_preset("davis346"), basis_times_s=np.array([0.0]),
                  current_basis=basis, waveforms=waveforms, duration_s=duration_s,
                  variant=types.SimpleNamespace(variant="none"), current_noise=None, render_quality={})
    return run(config, path, setup=setup).counts


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=0.1)
    ap.add_argument("--method", action="append", help="default: direct and dct")
    ap.add_argument("--keep", metavar="DIR", help="write the emulation here (reused if present)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        h5 = folder / "run.h5"
        if not h5.exists():
            counts = emulate(h5, args.duration_s)
            print(f"emulated {args.duration_s * 1e3:g} ms at 346x260: " +
                  ", ".join(f"{n / 1e6:.1f} M {k}" for k, n in counts.items()))
        for method in args.method or ["direct", "dct"]:
            start = time.perf_counter()
            argv = ["reconstruct", str(h5), "--method", method, "--out", str(folder / f"rec_{method}")]
            child = subprocess.run([sys.executable, "-c", CHILD, *argv], capture_output=True, text=True)
            if child.returncode:
                print(f"{method}: failed: {child.stderr.strip().splitlines()[-1]}")
                continue
            peak_kib = int(child.stdout.split()[-1])
            print(f"{method}: peak {peak_kib / 1024:.0f} MiB, {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
