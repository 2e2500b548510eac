"""One-pass light-group path tracer: K basis images from the same paths.

Light transport is linear in emitter radiance, so the radiance reaching a
pixel is the sum over emitters of what each contributes along the path. This
integrator traces every path once with all lamps on and adds each emitter
contribution (hits found by BSDF sampling and emitter samples, both with their
multiple-importance weights) to the accumulator of the emitter's light group.
The K images share their paths: their sum is an ordinary unidirectional path
tracer's image, and each one is, in expectation, that group rendered alone.

The estimator is the standard unidirectional path tracer with next-event
estimation and power-heuristic MIS (Veach 1997, ch. 9), as in Mitsuba 3's
``path`` plugin (``src/integrators/path.cpp``) and its Python ``prb``
integrator, which served as the model: same sampling order per vertex
(emitter sample, then BSDF sample, then Russian roulette from ``rr_depth``).
Only what the scenes of gevsim use is supported: surfaces, no participating
media, no polarisation, box pixel filter (each sample lands in its own pixel).

It runs in the JIT variants (``llvm_ad_*``, ``cuda_ad_*``): the whole
wavefront of ``width x height x spp`` paths is one compiled kernel. In scalar
variants a Python loop per path would be far too slow, so
:mod:`gevsim.render.basis` renders one group at a time with Mitsuba's built-in
``path`` instead (same expectation, K times the work).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


def supported(variant: str) -> bool:
    """Whether the one-pass integrator runs in this Mitsuba variant."""
    return variant.startswith(("llvm_", "cuda_")) and "polarized" not in variant


def _power_heuristic(pdf_a, pdf_b):
    import drjit as dr

    a2, b2 = dr.square(pdf_a), dr.square(pdf_b)
    return dr.detach(dr.select(pdf_a > 0, a2 / (a2 + b2), 0.0), True)


def _group_of(emitter, group_ptrs):
    """Per lane, the index of the emitter's light group (K when it is in none)."""
    import mitsuba as mi

    idx = mi.UInt32(len(group_ptrs))
    for k, ptrs in enumerate(group_ptrs):
        for p in ptrs:
            idx[emitter == p] = k
    return idx


def render_groups(scene: Any, groups: Sequence[Sequence], *, spp: int, seed: int, max_depth: int,
                  rr_depth: int = 5, grid: Any = None) -> np.ndarray:
    """Render K light-group images of ``scene`` from one set of paths.

    Parameters
    ----------
    scene : a loaded ``mitsuba.Scene`` (variant must satisfy :func:`supported`).
    groups : for each light group, the ``mitsuba.Emitter`` objects it holds.
    spp : samples per pixel (the sensor's sampler type is used; it may round
        the count, e.g. ``stratified`` to a square).
    seed : sampler seed; different seeds give independent images.
    max_depth : longest path, as Mitsuba's ``path`` (1: emitters seen directly).
    rr_depth : depth from which Russian roulette may end paths.
    grid : a :class:`~gevsim.render.rays.PinholeGrid` to render instead of the sensor's film (its
        cells are the pixels; the sensor's sampler still draws the samples). With the sensor's own
        grid (:func:`~gevsim.render.rays.sensor_grid`) the rays, and so the image, are the sensor's.

    Returns
    -------
    float32 (K, H, W, C) radiance: C = 1 in mono variants, else 3 (linear sRGB); H, W the grid's
    when one is given.
    """
    import drjit as dr
    import mitsuba as mi

    if not supported(mi.variant()):
        raise ValueError(f"render_groups needs a JIT variant (llvm/cuda, not polarized), got {mi.variant()!r}")
    if spp < 1 or max_depth < 1:
        raise ValueError(f"render_groups: spp and max_depth must be >= 1, got {spp} and {max_depth}")
    k_groups = len(groups)
    group_ptrs = [[mi.EmitterPtr(e) for e in g] for g in groups]
    sensor = scene.sensors()[0]
    film = sensor.film()
    width, height = (int(v) for v in film.crop_size()) if grid is None else (grid.width, grid.height)
    if grid is not None and mi.is_spectral:
        raise ValueError("render_groups: a PinholeGrid needs an RGB or mono variant (its rays carry no wavelengths)")
    sampler = sensor.sampler().clone()
    sampler.set_sample_count(spp)
    spp = sampler.sample_count()
    sampler.set_samples_per_wavefront(spp)
    n_paths = width * height * spp
    if n_paths >= 2**32:
        raise ValueError(f"render_groups: {width}x{height} at {spp} spp is over 2^32 paths; render in batches")
    sampler.seed(seed, n_paths)

    # Primary rays: sample i belongs to pixel i // spp, jittered uniformly inside it.
    pixel = dr.arange(mi.UInt32, n_paths) // spp
    px = mi.Vector2f(mi.Float(pixel % width), mi.Float(pixel // width)) + sampler.next_2d()
    if grid is None:
        wavelength_sample = sampler.next_1d() if mi.is_spectral else mi.Float(0.5)
        ray, ray_weight = sensor.sample_ray(sensor.shutter_open(), wavelength_sample,
                                            px / mi.ScalarVector2f(width, height), mi.Point2f(0.5))
    else:
        from gevsim.render.rays import primary_rays

        ray, ray_weight = primary_rays(grid, px, near_clip_m=float(sensor.near_clip())), mi.Spectrum(1.0)

    bsdf_ctx = mi.BSDFContext()

    def add(acc, lanes_group, value):
        return tuple(a + dr.select(lanes_group == k, value, 0.0) for k, a in enumerate(acc))

    def body(sampler, ray, beta, eta, depth, active, si_prev, pdf_prev, delta_prev, acc):
        si = scene.ray_intersect(ray, active)
        bsdf = si.bsdf(ray)

        # Emitter found by the previous BSDF sample (or seen directly), MIS-weighted.
        ds = mi.DirectionSample3f(scene, si=si, ref=si_prev)
        mis = dr.select(delta_prev, 1.0,
                        _power_heuristic(pdf_prev, scene.pdf_emitter_direction(si_prev, ds, ~delta_prev)))
        le = beta * mis * ds.emitter.eval(si, active)
        acc = add(acc, _group_of(ds.emitter, group_ptrs), dr.select(active, le, 0.0))

        active_next = active & (depth + 1 < max_depth) & si.is_valid()

        # Next-event estimation: one emitter sample, MIS against the BSDF.
        active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        ds_em, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(active_em), True, active_em)
        active_em &= ds_em.pdf != 0.0
        wo = si.to_local(ds_em.d)
        f_em, pdf_em = bsdf.eval_pdf(bsdf_ctx, si, wo, active_em)
        mis_em = dr.select(ds_em.delta, 1.0, _power_heuristic(ds_em.pdf, pdf_em))
        contribution = dr.select(active_em, beta * mis_em * f_em * em_weight, 0.0)
        acc = add(acc, _group_of(ds_em.emitter, group_ptrs), contribution)

        # Continue the path by sampling the BSDF.
        bs, bsdf_weight = bsdf.sample(bsdf_ctx, si, sampler.next_1d(active_next), sampler.next_2d(active_next),
                                      active_next)
        beta = beta * bsdf_weight
        eta = eta * bs.eta
        si_next_prev = dr.detach(si, True)
        pdf_next = bs.pdf
        delta_next = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
        ray = si.spawn_ray(si.to_world(bs.wo))

        beta_max = dr.max(mi.unpolarized_spectrum(beta))
        active_next &= beta_max != 0.0
        rr_prob = dr.minimum(beta_max * dr.square(eta), 0.95)
        rr_active = depth >= rr_depth
        beta = dr.select(rr_active, beta * dr.rcp(rr_prob), beta)
        rr_continue = sampler.next_1d(active_next) < rr_prob
        active_next &= ~rr_active | rr_continue
        return sampler, ray, beta, eta, depth + 1, active_next, si_next_prev, pdf_next, delta_next, acc

    zeros = tuple(dr.zeros(mi.Spectrum, n_paths) for _ in range(k_groups))
    # The sampler is loop state: its random-number state advances every bounce.
    state = (sampler, mi.Ray3f(ray), mi.Spectrum(ray_weight), mi.Float(1.0), mi.UInt32(0), mi.Bool(True),
             dr.zeros(mi.SurfaceInteraction3f, n_paths), mi.Float(1.0), mi.Bool(True), zeros)
    state = dr.while_loop(state, lambda *s: s[5], body, max_iterations=max_depth, label="gevsim light groups")
    acc = state[-1]

    channels = 1 if mi.is_monochromatic else 3
    image = dr.zeros(mi.Float, k_groups * width * height * channels)
    for k, value in enumerate(acc):
        if mi.is_spectral:
            value = mi.spectrum_to_srgb(value, ray.wavelengths)
        parts = [value.x] if channels == 1 else [value.x, value.y, value.z]
        for c, part in enumerate(parts):
            dr.scatter_reduce(dr.ReduceOp.Add, image, part, (k * width * height + pixel) * channels + c)
    out = np.array(image, dtype=np.float64).reshape(k_groups, height, width, channels) / spp
    return out.astype(np.float32)


def group_emitters(scene: Any, emitter_ids: Sequence[Sequence[str]]) -> list[list]:
    """The ``mitsuba.Emitter`` objects of each group, from shape or emitter ids.

    An id names an emitting shape (its area emitter is taken) or a standalone
    emitter (point, spot, constant, envmap, directional).
    """
    shapes = {s.id(): s for s in scene.shapes()}
    standalone = {e.id(): e for e in scene.emitters()}
    out = []
    for ids in emitter_ids:
        found = []
        for eid in ids:
            shape = shapes.get(eid)
            emitter = shape.emitter() if shape is not None else standalone.get(eid)
            if emitter is None:
                raise ValueError(f"no emitter with id {eid!r} in the scene")
            found.append(emitter)
        out.append(found)
    return out
