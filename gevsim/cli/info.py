"""``gevsim info``, ``presets``, ``scenes`` and ``validate``."""

from __future__ import annotations

import argparse
import sys

from gevsim.cli._common import _progress


def cmd_info(args: argparse.Namespace) -> int:
    import os

    from gevsim._lock import status
    from gevsim.experiments.executors import usable_cores
    from gevsim.render.backend import describe

    numba = (f"{os.environ['NUMBA_NUM_THREADS']} threads (NUMBA_NUM_THREADS)" if "NUMBA_NUM_THREADS" in os.environ
             else "a thread per CPU (NUMBA_NUM_THREADS unset)")
    threads = {"cores": f"{usable_cores()} usable; a pool of W workers gives each cores // W numba threads",
               "numba": f"{numba}; OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY', '(unset)')}"}
    for key, value in {**describe(), **threads, "lock": status()}.items():
        print(f"{key:>9}: {value}")
    return 0


def cmd_presets(args: argparse.Namespace) -> int:
    from gevsim.pixel.presets import listed_preset, preset_names

    print(f"{'preset':14s} {'size':>9s} {'pitch um':>8s} {'fill':>5s} {'ON/OFF ln':>11s} {'mismatch':>8s} "
          f"{'cutoff Hz':>9s} {'dark A':>9s} {'APS':>4s}  description")
    for name in preset_names():
        p = listed_preset(name)  # without the photometry that `emulate` needs: colour-science, numba
        e = p.events
        print(f"{name:14s} {f'{p.width}x{p.height}':>9s} {p.pixel_pitch_m * 1e6:8.2f} {p.fill_factor:5.2f} "
              f"{e.threshold_on_ln:5.3g}/{e.threshold_off_ln:<5.3g} {e.threshold_mismatch_ln:8.3g} "
              f"{p.photoreceptor.cutoff_hz:9.4g} {p.noise.dark_current_a:9.2g} {'yes' if p.aps else 'no':>4s}  "
              f"{p.description}")
    return 0


def cmd_scenes(args: argparse.Namespace) -> int:
    from gevsim.render import builtin_scenes, load

    for name, path in builtin_scenes().items():
        m = load(path)
        groups = ", ".join(f"{g.name} ({type(g.waveform).__name__})" for g in m.light_groups)
        print(f"{name:14s} {m.render.width}x{m.render.height} {m.duration_s * 1e3:.0f} ms  {groups}")
        print(f"{'':14s} {m.description}")
    return 0


def cmd_validate(args: argparse.Namespace) -> int:
    from gevsim.io.ownership import check_folder
    from gevsim.pixel import load_preset
    from gevsim.pixel.presets import preset_names
    from gevsim.validation.checks import Settings
    from gevsim.validation.report import check_sensor_names, validate, write

    names = args.sensor or [n for n in preset_names() if n != "ideal"]
    presets = [load_preset(n) for n in names]  # every name checked before any run
    check_sensor_names(presets)
    check_folder(args.out, "validation", inputs=[p.source for p in presets])  # before the runs: only an earlier
    # report is replaced, and never the folder holding a preset file it reads
    settings = Settings.quick() if args.quick else Settings()
    results = []
    for preset in presets:
        update, close = _progress(f"validate {preset.name}", not args.quiet, unit="check")
        try:
            rows, curves = validate(preset, settings=settings, progress=update)
        finally:
            close()
        results.append((preset, rows, curves))
        failed = [r for r in rows if r.verdict == "fail"]
        print(f"{preset.name}: {sum(r.verdict == 'pass' for r in rows)} passed, {len(failed)} failed"
              + "".join(f"\n  FAIL {r.check}: published {r.published}, model {r.model}" for r in failed))
    report = write(results, args.out, settings)
    print(f"gevsim: wrote {report}", file=sys.stderr)
    return 1 if any(r.verdict == "fail" for _, rows, _ in results for r in rows) else 0
