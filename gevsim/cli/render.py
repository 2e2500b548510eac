"""``gevsim render``: a scene's light-group basis (and an irradiance sequence)."""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING

from gevsim.cli._common import _progress
from gevsim.errors import ConfigError

if TYPE_CHECKING:
    from collections.abc import Sequence
    from pathlib import Path

    import numpy as np

    from gevsim.render.basis import BasisSet
    from gevsim.render.output import FramePlots


def cmd_render(args: argparse.Namespace) -> int:
    from gevsim.io.ownership import check_folder
    from gevsim.render import MitsubaScene, load, override, render_basis
    from gevsim.render.output import write_render
    from gevsim.resources import check_render_frames, check_writable

    manifest = load(args.scene)
    manifest = override(manifest, width=args.width, height=args.height, spp=args.spp, seed=args.seed,
                        noise_target_ln=args.noise_target, max_spp=args.max_spp, time_budget_s=args.time_budget,
                        denoise=args.denoise, duration_s=args.duration, source="command line")
    check_folder(args.out, "render", inputs=[*manifest.manifests, manifest.builder])  # before rendering
    check_writable(args.out)
    if args.frames is not None:  # their memory and disk, before rendering
        r = manifest.render
        check_render_frames(args.frames, manifest.duration_s, width=r.width, height=r.height,
                            channels=1 if r.flavour == "mono" else 3, out=args.out)
    if args.plots and args.frames is None:
        raise ConfigError("--plots needs --frames RATE (the plots show the mixed sequence)", key="--plots")
    if args.plots:
        from gevsim.plots import _pyplot

        _pyplot()
    start = time.perf_counter()
    scene = MitsubaScene(manifest)
    r = manifest.render
    quality = (f"noise target {r.noise_target_ln} ln at p{r.noise_percentile:g} (max {r.max_spp} spp)" if r.targeted
               else f"{r.spp} spp")
    print(f"gevsim: scene {manifest.name}, {r.width}x{r.height}, {quality}, {r.sampler} sampler, "
          f"variant {scene.variant.variant} ({scene.variant.reason}), "
          f"{'one pass for all light groups' if scene.one_pass else 'one render per light group'}", file=sys.stderr)
    update, close = _progress(f"render {manifest.name}", not args.quiet)
    try:
        basis = render_basis(scene, cache_dir=args.cache, progress=update)
    finally:
        close()
    rendered = int((basis.render_s > 0).sum())
    info = write_render(args.out, manifest, basis, variant=scene.variant, frame_rate_hz=args.frames,
                        exposure_s=args.exposure, plots=_plots(manifest.name) if args.plots else None)
    per = basis.render_s[basis.render_s > 0]
    timing = f", {per.mean():.2f} s per render" if per.size else ""
    q = basis.noise_summary()
    renders = len({str(k).split("/")[0] for k in basis.keys})  # a reused render's poses share its key
    how = "" if renders == len(basis.times_s) else f" resampled from {renders} {basis.quality[0]['reuse']} render(s)"
    print(f"gevsim: {len(basis.times_s)} poses x {len(basis.groups)} light groups{how}, {rendered} rendered, "
          f"{renders - rendered} from cache{timing}; {q['spp_min']}-{q['spp_max']} spp, "
          f"p{q['percentile']:g} ln error {q['se_ln']['at_percentile']:.4g}"
          f"{'' if q['reached'] else ' (target NOT reached: ' + ', '.join(q['stopped_by']) + ')'}; "
          f"{len(info.get('frames', {}).get('t_s', []))} frames; wrote {args.out} "
          f"in {time.perf_counter() - start:.1f} s", file=sys.stderr)
    return 0


def _plots(title: str) -> FramePlots:
    """What ``--plots`` draws into a render's folder: a contact sheet of the frames and the lamps' waveforms."""
    from gevsim import plots as plotting

    def draw(folder: Path, basis: BasisSet, frames: np.ndarray, times_s: list, mean_lux: Sequence[float]) -> None:
        plotting.contact_sheet(frames, times_s, folder / "contact_sheet.png", title=title)
        plotting.waveform_plot(basis, times_s, mean_lux, folder / "waveform.png", title=title)

    return draw
