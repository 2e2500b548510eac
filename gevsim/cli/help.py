"""What ``gevsim COMMAND --help`` says above the options: what the command does, what it writes,
and runnable examples (``tests/test_cli_options.py`` parses every example)."""

from __future__ import annotations

import textwrap

#: command -> (description: full sentences, examples: command lines starting with ``gevsim``)
COMMANDS: dict[str, tuple[str, list[str]]] = {
    "info": ("Print the versions of gevsim and its libraries, the Mitsuba variant gevsim chose and why (CPU "
             "features, libLLVM found or not), and the threads numba and Dr.Jit will use.",
             ["gevsim info"]),
    "scenes": ("List the built-in scenes with their size, duration and light groups (each lamp's waveform "
               "kind). A scene is named by these names in configs and on the command line, or given as a "
               "manifest .toml of your own.",
               ["gevsim scenes"]),
    "presets": ("List the sensor presets (ideal, dvs128, davis346, imx636, ...) with their size, thresholds, "
                "bandwidth, dark current and whether they have an APS; each preset's file cites its sources.",
                ["gevsim presets"]),
    "render": ("Render a scene's light-group basis images with Mitsuba 3 (one HDR image per light group, to the "
               "scene's noise target unless --spp is given), cache them, and with --frames write the irradiance "
               "sequence the lamps' waveforms make of them (HDF5), with --plots a contact sheet and a waveform "
               "plot. The output folder is written atomically.",
               ["gevsim render office --out out/office --width 96 --height 72 --frames 4000 --plots",
                "gevsim render scenes/office_pan.toml --out out/pan --spp 64 --duration 0.02"]),
    "emulate": ("Emulate events into one HDF5 file. Scene mode (a CONFIG.toml) renders the scene, turns its "
                "irradiance into photocurrent and runs the sensor preset's pixel (photoreceptor, noise, "
                "bandwidth, leak, refractory period, readout) and every emulator named (DVS, gradient, "
                "center-surround). Frame mode (--frames, --evreal or --video) runs on a frame sequence: the "
                "paper's ideal frame mode by default, or the physical pixel with --sensor and --illuminance-lux.",
                ["gevsim emulate experiments/office_small.toml --out out/office.h5",
                 "gevsim emulate --video clip.mp4 --sensor davis346 --illuminance-lux 5 --out out/clip.h5"]),
    "reconstruct": ("Reconstruct log-intensity frames from an emulation file's events with one or more methods "
                    "and score them against the file's ground truth (MSE, SSIM, PSNR as EVREAL computes them), "
                    "with each method's events and bandwidth. Writes frames, scores and a table.",
                    ["gevsim reconstruct out/office.h5 --method dct,direct --out out/office_rec"]),
    "export": ("Write an emulation file's events in a format another tool reads with its own code: AEDAT4 "
               "(DV, dv-processing, tonic), 't x y p' text with t in seconds (ESIM, E2VID, EVREAL tooling), "
               "NumPy .npz with tonic's fields, or an EVREAL sequence folder. The input is never changed, and "
               "only an earlier gevsim export is replaced.",
               ["gevsim export out/office.h5 --format aedat4 --out out/office.aedat4",
                "gevsim export out/office.h5 --format text --stream gradient_events --out out/gradient.txt"]),
    "view": ("Draw an emulation file's events as pictures: one per time window, a panel per stream (DVS and "
             "center-surround ON blue and OFF red; gradient X steps in red, Y in green) beside the ground-truth "
             "log frame, with a time bar. A .png holds up to 8 windows one under the other; .gif and .mp4 "
             "animate every window from --start-ms to --end-ms, each written as it is drawn, at most "
             "--max-frames of them (10,000: a longer span needs a longer --window-ms). A GIF stores whole 1/100 s "
             "delays (--fps 0.01-100), an MP4 0.01-1000 fps.",
             ["gevsim view out/office.h5 --out out/office.gif --window-ms 1",
              "gevsim view out/office.h5 --out out/office.png --streams events --start-ms 10"]),
    "dataset": ("Generate many randomised sequences (scenes, lamps, sensors, motions drawn from the config's "
                "distributions, each with its own seed) as HDF5 shards and EVREAL folders, with depth, flow and "
                "poses beside the events. Finished sequences are kept, so an interrupted dataset resumes.",
                ["gevsim dataset experiments/dataset_small.toml --out out/dataset --workers 2"]),
    "validate": ("Check sensor presets against published measurements (background activity against "
                 "illuminance, bandwidth, latency, threshold mismatch, readout) and against themselves (the "
                 "same answer with the time step halved and the start shifted). Writes a report with plots "
                 "and a pass/fail table, and exits non-zero when a check fails.",
                 ["gevsim validate --sensor davis346 --out out/validate --quick"]),
    "study": ("Run (or resume) a study: every run of its sweep, each repeated with several noise seeds and "
              "paired with its counterfactuals (no flicker, ideal pixel, render-noise floor), aggregated into "
              "intervals. Writes results.csv/json, per-pixel maps, plots, event strips and report.md.",
              ["gevsim study experiments/demo.toml --out out/demo_study",
               "gevsim study experiments/demo.toml --out out/demo_study --repeats 8 --workers 2"]),
    "score": ("Score reconstruction methods over many emulation files, or every shard of `gevsim dataset` folders "
              "(held-out sequences): per method and ground truth, the mean MSE and SSIM over the sequences with a 95 % "
              "Student-t interval. Writes table.md, ssim.png and results.json (every sequence's scores).",
              ["gevsim score out/heldout --method e2v,direct,dct,e2v_gradient --reference flicker,no-flicker "
               "--out out/heldout_scores"]),
    "train": ("Train the learned reconstruction (a FireNet-style recurrent network of ~38 k parameters) on a "
              "`gevsim dataset` for one event type, with the same loss, data and time budget for each. Writes "
              "the weights (.npz, which `gevsim reconstruct` runs without PyTorch), their provenance (.json) "
              "and the loss curve (.png). Needs PyTorch: pip install 'gevsim[learn]'.",
              ["gevsim train --events dvs --data out/dataset --out out/e2v_dvs.npz --minutes 10"]),
}


def description(command: str) -> str:
    """The --help text above the options: the command's description and its examples."""
    text, examples = COMMANDS[command]
    return textwrap.fill(text, 78) + "\n\nexamples:\n" + "\n".join(f"  {line}" for line in examples)
