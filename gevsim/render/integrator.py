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
(emitter samples, then BSDF sample, then Russian roulette from ``rr_depth``).
Only what the scenes of gevsim use is supported: surfaces, no participating
media, no polarisation, box pixel filter (each sample lands in its own pixel).

Next-event estimation draws one emitter sample *per light group* (an emitter
of the group, uniformly), where ``path`` draws one of all emitters: a
sum of K one-sample estimators, each MIS-weighted with its own pdf (Veach
1997, sec. 9.2.4). Each group's image then gets an emitter sample at every
vertex, instead of one time in (number of emitters); emitters in no group are
not sampled (their light goes into no image).

One technique is added to those two: a *light-vertex connection*, the
``s = 2`` strategy of bidirectional path tracing (Lafortune and Willems 1993;
Veach and Guibas 1995; Veach 1997, ch. 10). At a camera vertex x, a point y0
is sampled on an area emitter, a cosine-distributed ray from y0 finds y1, and
x is connected to y1. A path x -> y1 -> y0 can so be made three ways (BSDF
sample at x then at y1; BSDF sample at x then emitter sample at y1; the
connection), weighted with the power heuristic over the three pdfs; shorter
paths keep the two-way weights. It is what a small bright emitter close to a
surface needs: the patch of road a car's headlight lights is a secondary
source that BSDF sampling from elsewhere finds too rarely (street_night: the
headlights' light reflected by that patch was ~all of the p99 pixels' error).

It runs in the JIT variants (``llvm_ad_*``, ``cuda_ad_*``): the whole
wavefront of ``width x height x spp`` paths is one compiled kernel. In scalar
variants a Python loop per path would be far too slow, so
:mod:`gevsim.render.basis` renders one group at a time with Mitsuba's built-in
``path`` instead (same expectation, K times the work).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np


def supported(variant: str) -> bool:
    """Whether the one-pass integrator runs in this Mitsuba variant."""
    return variant.startswith(("llvm_", "cuda_")) and "polarized" not in variant


def _power_heuristic3(pdf_a, pdf_b, pdf_c):
    """Power-heuristic weight of the technique with pdf ``pdf_a`` against two others (Veach 1997, eq. 9.13),
    written as 1 / (1 + (b/a)^2 + (c/a)^2): 1 where ``pdf_a`` is infinite, 0 where it is 0."""
    import drjit as dr

    w = dr.rcp(1.0 + dr.square(pdf_b / pdf_a) + dr.square(pdf_c / pdf_a))
    return dr.detach(dr.select(pdf_a > 0, w, 0.0), True)


def _is_one_of(emitter, ptrs):
    import mitsuba as mi

    out = mi.Bool(False)
    for p in ptrs:
        out |= emitter == p
    return out


def _pick(ptrs, u):
    """Per lane, one of ``ptrs`` chosen uniformly by the uniform number ``u``."""
    import drjit as dr
    import mitsuba as mi

    index = dr.minimum(mi.UInt32(u * len(ptrs)), len(ptrs) - 1)
    emitter = dr.zeros(mi.EmitterPtr, dr.width(u))
    for i, p in enumerate(ptrs):
        emitter = dr.select(index == i, p, emitter)
    return emitter


def _nee_selection(emitter, group_ptrs):
    """Per lane, the probability that the per-group emitter samples pick ``emitter``: each group draws
    one of its emitters uniformly, so 1/|group| (summed if listed in several); 0 outside every group."""
    import drjit as dr
    import mitsuba as mi

    pdf = mi.Float(0.0)
    for ptrs in group_ptrs:
        for p in ptrs:
            pdf += dr.select(emitter == p, 1.0 / len(ptrs), 0.0)
    return pdf


def _connection_ratio(emitter, y0_p, y0_n, y1, pdf_x_y1, area_ptrs):
    """The light-vertex connection's pdf of the path x -> y1 -> y0, over the area pdf ``pdf_x_y1`` of
    BSDF-sampling y1 from x: in solid angle at y1, the unit of the emitter sample's and BSDF sample's
    pdfs it is weighed against. It is ``p_sel p_pos(y0) |cos y1| / pi / pdf_x_y1`` (the emitted direction is
    cosine-distributed, so the cosine at y0 and the distance cancel); 0 where the connection cannot make
    the path (not an area emitter, ``pdf_x_y1 = 0``)."""
    import drjit as dr
    import mitsuba as mi

    cos_y1 = dr.abs(dr.dot(y1.n, dr.normalize(y0_p - y1.p)))
    ps = dr.zeros(mi.PositionSample3f, dr.width(cos_y1))
    ps.p, ps.n = y0_p, y0_n
    pdf = emitter.get_shape().pdf_position(ps) * cos_y1 * dr.inv_pi / max(len(area_ptrs), 1)
    return dr.select(_is_one_of(emitter, area_ptrs) & (pdf_x_y1 > 0), pdf / pdf_x_y1, 0.0)


def _light_vertex(sampler, si, area_ptrs, active):
    """Sample y0 on an area emitter (chosen uniformly, uniform by area) and a cosine-weighted ray from
    it; return ``(emitter, y0 position sample, ray, weight)``, weight = L_e pi / (p_sel p_pos)."""
    import drjit as dr
    import mitsuba as mi

    emitter = _pick(area_ptrs, sampler.next_1d(active))
    ps = emitter.get_shape().sample_position(si.time, sampler.next_2d(active), active)
    local = mi.warp.square_to_cosine_hemisphere(sampler.next_2d(active))
    y0 = mi.SurfaceInteraction3f(ps, si.wavelengths)
    y0.sh_frame, y0.wi = mi.Frame3f(ps.n), local
    weight = emitter.eval(y0, active) * (dr.pi * len(area_ptrs)) / ps.pdf
    return emitter, ps, y0.spawn_ray(y0.sh_frame.to_world(local)), weight


def _group_of(emitter, group_ptrs):
    """Per lane, the index of the emitter's light group (K when it is in none)."""
    import mitsuba as mi

    idx = mi.UInt32(len(group_ptrs))
    for k, ptrs in enumerate(group_ptrs):
        for p in ptrs:
            idx[emitter == p] = k
    return idx


def padded_count(n: int) -> int:
    """The least size >= ``n`` of the ladder round(2^(j/2)) (at most 42 % more): the pixel counts a subset
    render is padded to, so that its compiled kernels are few and stay in Dr.Jit's cache."""
    j = max(0, math.ceil(2 * math.log2(max(n, 1)) - 1e-9))
    while round(2 ** (j / 2)) < n:
        j += 1
    return max(n, round(2 ** (j / 2)))


def render_groups(scene: Any, groups: Sequence[Sequence], *, spp: int, seed: int, max_depth: int,
                  rr_depth: int = 5, grid: Any = None, pixels: Any = None) -> np.ndarray:
    """Render K light-group images of ``scene`` from one set of paths. (Over 80 lines: one Dr.Jit kernel;
    its path-tracing closures share the traced scene, groups and sampler.)

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
    pixels : flat indices (row * width + column) of the only pixels to render (those a reuse
        method could not reuse); all when None.

    Returns
    -------
    float32 (K, H, W, C) radiance: C = 1 in mono variants, else 3 (linear sRGB); H, W the grid's
    when one is given; (K, 1, N, C) for N ``pixels``.
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
    if pixels is not None:  # padded to a size from a short ladder: Dr.Jit compiles the kernel anew for every
        # path count (~0.5 s; measured), and reuse methods ask for a different number of pixels every time
        asked = np.asarray(pixels, np.int64).ravel()
        if asked.size == 0:
            raise ValueError("render_groups: pixels is empty")
        size = padded_count(asked.size)
        pixels = np.concatenate([asked, np.full(size - asked.size, asked[0])])
    n_pixels = width * height if pixels is None else len(pixels)
    n_paths = n_pixels * spp
    if n_paths >= 2**32:
        raise ValueError(f"render_groups: {width}x{height} at {spp} spp is over 2^32 paths; render in batches")
    sampler.seed(seed, n_paths)

    # Primary rays: sample i belongs to pixel i // spp, jittered uniformly inside it.
    local = dr.arange(mi.UInt32, n_paths) // spp  # the pixel's place in the output
    pixel = local if pixels is None else dr.gather(mi.UInt32, mi.UInt32(np.asarray(pixels, np.uint32)), local)
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

    # Only grouped emitters are sampled: light outside every group is in no image.
    area = {id(e): e for g in groups for e in g if mi.has_flag(e.flags(), mi.EmitterFlags.Surface)}
    area_ptrs = [mi.EmitterPtr(e) for e in area.values()]

    def nee_pdf(ref, ds, active):
        """Solid-angle pdf of the per-group emitter samples at ``ref`` for the direction sample ``ds``."""
        return ds.emitter.pdf_direction(ref, ds, active) * _nee_selection(ds.emitter, group_ptrs)

    def next_event(sampler, si, bsdf, beta, pdf_area, active, acc):
        """Next-event estimation, one emitter sample per light group (an emitter of the group, uniformly;
        Mitsuba's ``Scene::sample_emitter_direction`` draws one of all emitters instead), MIS-weighted
        against the BSDF sample and the connection."""
        for ptrs in group_ptrs:
            if not ptrs:
                continue
            emitter = _pick(ptrs, sampler.next_1d(active))
            ds, em_weight = emitter.sample_direction(si, sampler.next_2d(active), active)
            ds.emitter = emitter
            selection = _nee_selection(emitter, group_ptrs)
            active_em = active & (ds.pdf != 0.0)
            active_em &= ~scene.ray_test(si.spawn_ray_to(ds.p), active_em)
            f_em, pdf_bsdf = bsdf.eval_pdf(bsdf_ctx, si, si.to_local(ds.d), active_em)
            ratio = _connection_ratio(emitter, ds.p, ds.n, si, pdf_area, area_ptrs)
            mis = dr.select(ds.delta, 1.0, _power_heuristic3(ds.pdf * selection, pdf_bsdf, ratio))
            contribution = dr.select(active_em, beta * mis * f_em * em_weight / selection, 0.0)
            acc = add(acc, _group_of(emitter, group_ptrs), contribution)
        return acc

    def connect(sampler, si, bsdf, beta, active, acc):
        """Light-vertex connection at camera vertex ``si``: y0 on an emitter, y1 where its ray lands."""
        emitter, y0, light_ray, light_weight = _light_vertex(sampler, si, area_ptrs, active)
        y1 = scene.ray_intersect(light_ray, active)
        bsdf_y1 = y1.bsdf(light_ray)
        active &= y1.is_valid() & mi.has_flag(bsdf_y1.flags(), mi.BSDFFlags.Smooth)
        to_y1 = y1.p - si.p
        dist2 = dr.squared_norm(to_y1)
        to_y1 = to_y1 * dr.rsqrt(dist2)
        active &= ~scene.ray_test(si.spawn_ray_to(y1.p), active)
        f_x, pdf_x = bsdf.eval_pdf(bsdf_ctx, si, si.to_local(to_y1), active)
        y1.wi = y1.to_local(-to_y1)  # seen from the camera side, as a path tracer would reach it
        f_y1, pdf_y1 = bsdf_y1.eval_pdf(bsdf_ctx, y1, y1.to_local(-light_ray.d), active)
        cos_x_side, cos_light_side = dr.abs(dr.dot(y1.n, to_y1)), dr.abs(dr.dot(y1.n, light_ray.d))
        # The other two techniques' pdfs for this path, in solid angle at y1 (BSDF sample, emitter sample).
        ds = mi.DirectionSample3f(y0)
        ds.d, ds.dist, ds.emitter = -light_ray.d, dr.norm(y0.p - y1.p), emitter
        pdf_em = nee_pdf(y1, ds, active)
        ratio = _connection_ratio(emitter, y0.p, y0.n, y1, pdf_x * cos_x_side / dist2, area_ptrs)
        mis = _power_heuristic3(ratio, pdf_y1, pdf_em)
        # f_y1 carries the cosine toward y0, which the light's pdf has cancelled: swap it for the one toward x.
        value = beta * f_x * f_y1 * light_weight * mis * cos_x_side / (dist2 * dr.maximum(cos_light_side, 1e-12))
        return add(acc, _group_of(emitter, group_ptrs), dr.select(active, value, 0.0))

    def body(sampler, ray, beta, eta, depth, active, si_prev, pdf_prev, delta_prev, pdf_prev_area, acc):
        si = scene.ray_intersect(ray, active)
        bsdf = si.bsdf(ray)
        smooth = mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        # Area pdf of BSDF-sampling si from si_prev, where a connection from si_prev could also make
        # the paths through si (si_prev a surface, smooth-sampled, the path short enough); else 0.
        pdf_area = dr.select((depth >= 1) & ~delta_prev & smooth & si.is_valid() & (depth + 1 < max_depth),
                             pdf_prev * dr.abs(dr.dot(si.n, ray.d)) / dr.square(si.t), 0.0)

        # Emitter found by the previous BSDF sample (or seen directly), MIS-weighted.
        ds = mi.DirectionSample3f(scene, si=si, ref=si_prev)
        pdf_em = nee_pdf(si_prev, ds, ~delta_prev)
        ratio = _connection_ratio(ds.emitter, si.p, si.n, si_prev, pdf_prev_area, area_ptrs)
        mis = dr.select(delta_prev, 1.0, _power_heuristic3(pdf_prev, pdf_em, ratio))
        le = beta * mis * ds.emitter.eval(si, active)
        acc = add(acc, _group_of(ds.emitter, group_ptrs), dr.select(active, le, 0.0))

        active_next = active & (depth + 1 < max_depth) & si.is_valid()

        acc = next_event(sampler, si, bsdf, beta, pdf_area, active_next & smooth, acc)
        if area_ptrs:  # paths x -> y1 -> y0 of at most max_depth segments
            acc = connect(sampler, si, bsdf, beta, active_next & smooth & (depth + 2 < max_depth), acc)

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
        return sampler, ray, beta, eta, depth + 1, active_next, si_next_prev, pdf_next, delta_next, pdf_area, acc

    zeros = tuple(dr.zeros(mi.Spectrum, n_paths) for _ in range(k_groups))
    # The sampler is loop state: its random-number state advances every bounce.
    state = (sampler, mi.Ray3f(ray), mi.Spectrum(ray_weight), mi.Float(1.0), mi.UInt32(0), mi.Bool(True),
             dr.zeros(mi.SurfaceInteraction3f, n_paths), mi.Float(1.0), mi.Bool(True), mi.Float(0.0), zeros)
    state = dr.while_loop(state, lambda *s: s[5], body, max_iterations=max_depth, label="gevsim light groups")
    acc = state[-1]

    channels = 1 if mi.is_monochromatic else 3
    image = dr.zeros(mi.Float, k_groups * n_pixels * channels)
    for k, value in enumerate(acc):
        if mi.is_spectral:
            value = mi.spectrum_to_srgb(value, ray.wavelengths)
        parts = [value.x] if channels == 1 else [value.x, value.y, value.z]
        for c, part in enumerate(parts):
            dr.scatter_reduce(dr.ReduceOp.Add, image, part, (k * n_pixels + local) * channels + c)
    shape = (height, width) if pixels is None else (1, n_pixels)
    out = np.array(image, dtype=np.float64).reshape(k_groups, *shape, channels) / spp
    if pixels is not None:
        out = out[:, :, :asked.size]  # the padding's pixels are dropped
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
