"""Is the flicker-induced event rate converged in the render's knobs (spp, noise target, seed, denoiser)?

Office scene (static camera) at 128x96 with the ``ideal`` sensor (no pixel
noise, no threshold mismatch), so every event is caused by lamp flicker, or by
render noise re-mixed by it. Each setting is one emulation of ``--duration``
seconds with the DVS and the gradient emulator; the rate is events per pixel
per second. Beside each rate, the render-noise floor
(:func:`gevsim.emulation.driver.render_noise_floor` at the lamp's 500 Hz): what
the study reports as render noise's share, to be checked against the excess
over the reference. Renders are cached in ``--cache`` (a reference at 65536 spp takes
a few minutes on 2 cores), so settings can be added run by run.

Settings are given as ``label:key=value,key=value`` with [render] keys
(``spp``, ``seed``, ``noise_target_ln``, ``max_spp``, ``denoise``), e.g.::

    python benchmarks/flicker_convergence.py ref1:spp=65536,seed=11 \
        default:seed=1 half:seed=1,noise_target_ln=0.0025

Prints one line per setting and appends it as JSON to ``--json`` if given.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from gevsim.emulation import EmulationConfig, prepare, run
from gevsim.emulation.driver import render_noise_floor

#: The office's ceiling panel: PWM at 500 Hz. The floor redraws the render noise at this rate.
LAMP_HZ = 500.0

BASE_RENDER = {"width": 128, "height": 96, "noise_target_ln": "auto", "max_spp": 4096}


def parse_setting(text: str) -> tuple[str, dict]:
    label, _, body = text.partition(":")
    render = {}
    for item in filter(None, body.split(",")):
        key, _, value = item.partition("=")
        if value in ("true", "false"):
            render[key] = value == "true"
        elif value == "auto":
            render[key] = value
        else:
            number = float(value)
            render[key] = int(number) if number.is_integer() and key in ("spp", "seed", "max_spp") else number
    return label, render


def measure(label: str, render: dict, *, duration_s: float, cache: Path) -> dict:
    settings = dict(BASE_RENDER, **render)
    if "spp" in render:
        settings.pop("noise_target_ln")
    config = EmulationConfig(scene="office", sensor="ideal", emulators=("dvs", "gradient"), seed=1,
                             duration_s=duration_s, step_s=2e-5, chunk_steps=250, frame_rate_hz=0.0,
                             render=settings)
    start = time.perf_counter()
    setup = prepare(config, cache_dir=cache)
    render_s = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as tmp:
        summary = run(config, Path(tmp) / "run.h5", setup=setup)
        floor = run(config, Path(tmp) / "floor.h5", setup=render_noise_floor(setup, frequency_hz=LAMP_HZ))
    px = summary.width * summary.height
    q = setup.render_quality
    return {"label": label, "render": settings,
            "gradient_ev_px_s": summary.rates_hz["gradient_events"] / px,
            "dvs_ev_px_s": summary.rates_hz["events"] / px,
            "gradient_floor_ev_px_s": floor.rates_hz["gradient_events"] / px,
            "dvs_floor_ev_px_s": floor.rates_hz["events"] / px,
            "spp": q.get("spp_max"), "se_ln_p99": q.get("se_ln", {}).get("at_percentile"),
            "denoised": q.get("denoised"), "render_s": q.get("render_s"), "load_s": render_s,
            "emulate_s": summary.total_s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("settings", nargs="+", help="label:key=value,... ([render] overrides)")
    ap.add_argument("--duration", type=float, default=0.02, help="seconds emulated (default: ten PWM periods)")
    ap.add_argument("--cache", type=Path, default=Path(".gevsim-cache/flicker_convergence"))
    ap.add_argument("--json", type=Path, help="append each result as a JSON line")
    args = ap.parse_args()
    print(f"{'label':14s} {'gradient ev/px/s':>16s} {'DVS ev/px/s':>12s} {'floor grad.':>11s} {'floor DVS':>9s} "
          f"{'spp':>6s} {'p99 se_ln':>9s} {'denoised':>8s} {'render s':>8s}")
    for text in args.settings:
        label, render = parse_setting(text)
        r = measure(label, render, duration_s=args.duration, cache=args.cache)
        print(f"{label:14s} {r['gradient_ev_px_s']:16.2f} {r['dvs_ev_px_s']:12.2f} {r['gradient_floor_ev_px_s']:11.2f} "
              f"{r['dvs_floor_ev_px_s']:9.2f} {r['spp']:6d} "
              f"{r['se_ln_p99']:9.4f} {str(r['denoised']):>8s} {r['render_s']:8.1f}", flush=True)
        if args.json:
            with args.json.open("a") as f:
                f.write(json.dumps(r, default=float) + "\n")


if __name__ == "__main__":
    main()
