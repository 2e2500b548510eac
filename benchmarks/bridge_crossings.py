"""Route B of docs/long-steps.md, measured: noise-event rates of a DVS that sees the photoreceptor only every h,
with and without a Brownian-bridge crossing rule between the samples, against the physics-valid short steps.

A davis346 pixel array on a static log-normal texture (:func:`scene`) at a chip illuminance is started
as a running sensor (``gevsim.validation.measure.start_running``). Three paths then run over the same span from
copies of that start (independent noise, the same law):

- ``reference``: the driver's sub-steps (``coarsest_step_s``), today's DVS kernel: the rate every route must keep;
- ``sampled``: the photoreceptor's exact transition over h, today's DVS kernel on those samples alone (the
  crossings between samples are lost: what the short step exists for);
- ``bridge``: the same samples; between two samples d0, d1 of the distance to a level that both leave inside
  the thresholds, a crossing of level b with probability exp(-2 (b - d0)(b - d1) / (D h)) (a Brownian bridge;
  the leak's drift changes nothing given both ends), D = Var[y(t + h) - y(t)] / h of this very array's
  samples (the diffusion at lag h). On a crossing the pixel fires and its distance at the step's end is
  d1 - b minus the reset noise. A sample beyond a threshold fires as today's kernel does.

Rates are events per pixel per second (ON + OFF) with their 95 % intervals from per-pixel counts.
    .venv/bin/python benchmarks/bridge_crossings.py [--lux 0.1 1 10] [--steps-us 100 250 500 1000] [--span 1.0]
"""

from __future__ import annotations

import argparse
import copy
import math
import time

import numpy as np

from gevsim import _portable as pm
from gevsim.events.bridge import crossings
from gevsim.pixel import load_preset
from gevsim.pixel._cascade import separated_hz
from gevsim.pixel.noise import coarsest_step_s
from gevsim.validation.measure import photocurrent_a, running_sensor, start_running

#: Seconds in the rice rule and pixel-steps it saw (its cost).
RULE_S = [0.0, 0]

#: Ways to set the bridge's spread (see :func:`bridge_path`).
VARIANTS = ("lag", "slow", "smooth", "ou", "rice")


def scene(shape: tuple[int, int], preset, chip_lux: float) -> np.ndarray:
    """Photocurrent (A) of a static log-normal texture (sigma 0.5 ln) around ``chip_lux``."""
    z = np.random.default_rng(7).standard_normal(shape)
    return photocurrent_a(preset, chip_lux) * pm.exp(0.5 * z - 0.125)


def rate(counts: np.ndarray, span_s: float) -> tuple[float, float]:
    """Mean events per pixel per second and its 95 % half-width over pixels."""
    r = counts / span_s
    return float(r.mean()), 1.96 * float(r.std(ddof=1)) / math.sqrt(len(r))


def per_pixel(events: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    return np.bincount(events["y"].astype(np.int64) * shape[1] + events["x"], minlength=shape[0] * shape[1])


def bridge_path(pr, dvs, light, t0: float, h: float, steps: int, seed: int, *, variant: str,
                f_out_hz: float, light_mean=None) -> np.ndarray:
    """Per-pixel counts of the bridge rule over ``steps`` steps of ``h`` (see the module docstring). ``variant``:
    ``lag`` (D from the samples' variance at lag h), ``slow`` (D from the lags h and 2h: the slow part's
    diffusion, without the fast read noise's constant share), ``smooth`` (``slow``, and each bridge's level
    moved out by 1.03 sqrt(D / beta), the output pole's smoothing: Fourcaud & Brunel 2002)."""
    rng = np.random.default_rng(seed)
    n = dvs.threshold_on_ln.size
    on, off = dvs.threshold_on_ln.copy(), dvs.threshold_off_ln.copy()
    ref, y0 = dvs.ref.copy(), dvs.v_prev.copy()
    counts = np.zeros(n, np.int64)
    t = t0 + h * np.arange(1, steps + 1)
    ys = []
    for a in range(0, steps, 256):
        tt = t[a:a + 256]
        ys.append(pr.process(light(tt, h), tt).reshape(len(tt), n))
    y = np.concatenate(ys).astype(np.float64)
    lag1 = float(np.var(np.diff(y[1:], axis=0)))
    lag2 = float(np.var(y[2:] - y[:-2]))
    diffusion = lag1 / h if variant == "lag" else (lag2 - lag1) / h
    shift = 1.03 * math.sqrt(diffusion / (2 * math.pi * f_out_hz)) if variant == "smooth" else 0.0
    if variant == "ou":  # each pixel's photoreceptor pole: rate alpha, stationary variance at the output
        itot = np.asarray(pr.settled_current_a, float).reshape(-1)
        fc = separated_hz(pr.params.cutoff_at(itot), f_out_hz)
        alpha, beta = 2 * math.pi * fc, 2 * math.pi * f_out_hz
        var = (pr.shot_q * fc / itot + pr.amp_ln2_hz / fc) * beta / (alpha + beta)
        scale = var * np.sinh(alpha * h)  # P = exp(-(b - d0)(b - d1) / (var sinh(alpha h))): the OU bridge, chord
    if variant == "rice":  # Rice's formula on the Gaussian bridge of the output noise (gevsim.events.bridge)
        var_k, rate_k = pr.noise_components()
        beta = 2 * math.pi * f_out_hz
        mu = np.asarray(pr.settled_ln, float).reshape(-1)
        mean = light_mean if light_mean is not None else (lambda tt: mu)
    reset = float(dvs.params.reset_noise_ln)
    for k in range(steps):
        y1 = y[k]
        leak = dvs.leak_ln_per_s + (dvs.leak_light * pm.exp(y0) if dvs.leak_light.size else 0.0)
        d0 = y0 - ref
        d1 = y1 - ref + leak * h
        while True:  # samples beyond a threshold: today's rule, one threshold at a time
            up, down = d1 >= on, d1 <= -off
            if not (up.any() or down.any()):
                break
            counts += up | down
            d1 = np.where(up, d1 - on, np.where(down, d1 + off, d1)) - reset * rng.standard_normal(n) * (up | down)
            d0 = np.where(up | down, 0.0, d0)
        if variant == "rice":
            x0, x1 = y0 - mean(t[k] - h), y1 - mean(t[k])
            tick = time.perf_counter()
            p_on, p_off, _, _ = crossings(x0, x1, (on - d0, on - d1), (off + d0, off + d1), h, var_k, rate_k, beta)
            RULE_S[0] += time.perf_counter() - tick
            RULE_S[1] += n
        else:
            b_on, b_off = on + shift, off + shift
            spread = scale / 2.0 if variant == "ou" else diffusion * h
            p_on = np.exp(-2.0 * np.maximum(b_on - d0, 0.0) * np.maximum(b_on - d1, 0.0) / spread)
            p_off = np.exp(-2.0 * np.maximum(b_off + d0, 0.0) * np.maximum(b_off + d1, 0.0) / spread)
        u = rng.random(n)
        fire_on = u < p_on
        fire_off = ~fire_on & (u < p_on + p_off)
        counts += fire_on | fire_off
        d1 = np.where(fire_on, d1 - on, np.where(fire_off, d1 + off, d1))
        d1 = d1 - reset * rng.standard_normal(n) * (fire_on | fire_off)
        ref = y1 - d1
        y0 = y1
    return counts


def lighting(level: np.ndarray, t0: float, sine_ln: float, sine_hz: float):
    """light(t, dt): the photocurrent (len(t), H, W) held over each step of ``dt`` ending at t, its value at the
    step's middle: ``level`` times exp(sine_ln sin(2 pi sine_hz (t - t0)))."""
    def light(t: np.ndarray, dt: float) -> np.ndarray:
        if sine_ln == 0.0:
            return np.broadcast_to(level, (len(t),) + level.shape)
        gain = pm.exp(sine_ln * np.sin(2 * math.pi * sine_hz * (t - 0.5 * dt - t0)))
        return level[None] * gain[:, None, None]
    return light


def noise_free(pr, t0: float, sine_ln: float, sine_hz: float):
    """mean(t): each pixel's noise-free output at t (ln), the settled level plus the sinusoid through the
    photoreceptor's pole at its settled light and the output pole (steady state); None for a static light."""
    if sine_ln == 0.0:
        return None
    mu = np.asarray(pr.settled_ln, float).reshape(-1)
    f_out = pr.params.second_pole_hz
    fc = separated_hz(pr.params.cutoff_at(np.asarray(pr.settled_current_a, float).reshape(-1)), f_out)
    gain = 1.0 / ((1.0 + 1j * sine_hz / fc) * (1.0 + 1j * sine_hz / f_out))

    def mean(t: float) -> np.ndarray:
        return mu + sine_ln * np.imag(gain * np.exp(1j * 2 * math.pi * sine_hz * (t - t0)))
    return mean


def reference_path(pr, dvs, light, t0: float, span_s: float, step: float) -> None:
    """The driver's path: the chain at ``step`` over (t0, t0 + span_s], light held per step."""
    t = t0 + step * np.arange(1, int(round(span_s / step)) + 1)
    chunk = max(1, 2_000_000 // dvs.threshold_on_ln.size)
    for a in range(0, len(t), chunk):
        tt = t[a:a + chunk]
        dvs.process(pr.process(light(tt, step), tt), tt)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lux", type=float, nargs="*", default=[0.1, 1.0, 10.0])
    ap.add_argument("--steps-us", type=float, nargs="*", default=[100.0, 250.0, 500.0, 1000.0])
    ap.add_argument("--span", type=float, default=1.0, help="simulated seconds per path")
    ap.add_argument("--size", default="64x64")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--sine-ln", type=float, default=0.0, help="the light's log modulation (0: static)")
    ap.add_argument("--sine-hz", type=float, default=5.0)
    ap.add_argument("--ref-step-us", type=float, default=None,
                    help="the reference's step (default: the driver's, coarsest_step_s at most 20 us)")
    args = ap.parse_args()
    w, hgt = (int(x) for x in args.size.split("x"))
    shape = (hgt, w)
    preset = load_preset("davis346")
    light_text = (f"x exp({args.sine_ln:g} sin(2 pi {args.sine_hz:g} Hz t))" if args.sine_ln else "static")
    print(f"davis346, {w}x{hgt} px, log-normal texture, {light_text}, {args.span:g} s per path; ev/px/s (95 %)")
    print("| chip lux | reference step | reference | h | sampled | " + " | ".join(f"bridge ({v})" for v in args.variants)
          + " |")
    print("| --- " * (5 + len(args.variants)) + "|")
    zeros = np.zeros(1)
    crossings(zeros, zeros, (zeros + 1, zeros + 1), (zeros + 1, zeros + 1), 1e-3, [[1.0]], [[1.0]], 2.0)  # load the kernel
    for lux in args.lux:
        level = scene(shape, preset, lux)
        step = min(2e-5, coarsest_step_s(preset.photoreceptor, preset.noise, float(level.max())) or 2e-5)
        step = step if args.ref_step_us is None else args.ref_step_us * 1e-6
        pr, dvs = running_sensor(preset, shape, 1)
        t0 = start_running(pr, dvs, level[None], step)
        light = lighting(level, t0, args.sine_ln, args.sine_hz)
        p2, d2 = copy.deepcopy(pr), copy.deepcopy(dvs)
        tick = time.perf_counter()
        reference_path(p2, d2, light, t0, args.span, step)
        s_ref = time.perf_counter() - tick
        ref_counts = d2.count - dvs.count
        r_ref = rate(ref_counts, args.span)
        for h_us in args.steps_us:
            h = h_us * 1e-6
            steps = int(round(args.span / h))
            p3, d3 = copy.deepcopy(pr), copy.deepcopy(dvs)
            tt = t0 + h * np.arange(1, steps + 1)
            before = d3.count.copy()
            tick = time.perf_counter()
            for a in range(0, steps, 256):
                d3.process(p3.process(light(tt[a:a + 256], h), tt[a:a + 256]), tt[a:a + 256])
            s_sampled = time.perf_counter() - tick
            r_s = rate(d3.count - before, args.span)
            cells = []
            for variant in args.variants:
                r_b = rate(bridge_path(copy.deepcopy(pr), copy.deepcopy(dvs), light, t0, h, steps, seed=int(h_us),
                                       variant=variant, f_out_hz=preset.photoreceptor.second_pole_hz,
                                       light_mean=noise_free(pr, t0, args.sine_ln, args.sine_hz)), args.span)
                cells.append(f"{r_b[0]:.2f} ± {r_b[1]:.2f} ({r_b[0] / r_ref[0]:.3f})")
                if variant == "rice" and RULE_S[1]:  # its cost: the chain at h and the rule, against the reference's
                    cells[-1] += (f" [{RULE_S[0] / RULE_S[1] * 1e9:.0f} ns/px-step; "
                                  f"{s_ref / (s_sampled + RULE_S[0]):.1f}x cheaper]")
                    RULE_S[:] = [0.0, 0]
            print(f"| {lux:g} | {step * 1e6:.1f} us | {r_ref[0]:.2f} ± {r_ref[1]:.2f} | {h_us:g} us | "
                  f"{r_s[0]:.2f} ± {r_s[1]:.2f} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
