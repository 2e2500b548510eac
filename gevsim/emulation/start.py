"""How a run starts: a sensor that has been running (issue 22: the photoreceptor at the lamps'
periodic steady state; issue 34: every memory of the chain at its stationary state).

The photoreceptor's filters and noise are set exactly (:meth:`~gevsim.pixel.Photoreceptor.settle`
solves the periodic steady state and draws the noise from its stationary law). The event circuits'
memories (the DVS and CSDVS memorised levels, refractory timers and leak phases, the gradient
comparators' ternary state) are slower and have no closed-form law: their stationary state depends
on how often each pixel's noise has made it fire. :func:`burn_in` runs the whole chain for
``burn_in_s`` before t = 0 on the settled signal (the lamps' periodic light, the poses of t = 0) and
discards its events, so a run's rates are flat in time from t = 0. How long is long enough is measured
(``benchmarks/README.md``, issue 34's note): the slowest memory is a DVS level, renewed by its pixel's
own events.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from gevsim.emulation.bridging import Bridging, process_kwargs
from gevsim.emulation.emulators import EMULATORS
from gevsim.emulation.photocurrent import Setup, photocurrent_at
from gevsim.illumination import weights_at
from gevsim.pixel import Photoreceptor

#: The longest lamp period for which a run starts at the periodic steady state (one period is
#: emulated three times, noise-free, to solve for it).
MAX_SETTLE_PERIOD_S = 0.1


def common_period_s(waveforms: tuple | list) -> float | None:
    """The shortest time after which every waveform repeats (None: one is not periodic or the
    common period exceeds :data:`MAX_SETTLE_PERIOD_S`); 0.0 when all are constant."""
    from gevsim.illumination import DC

    found = [wf.period_s for wf in waveforms if not isinstance(wf, DC)]
    if any(p is None for p in found):
        return None
    periods = [float(p) for p in found]
    if not periods:
        return 0.0
    longest = max(periods)
    for k in range(1, int(MAX_SETTLE_PERIOD_S / longest) + 1):
        total = k * longest
        if all(abs(total / p - round(total / p)) < 1e-6 for p in periods):
            return total
    return None


def settle(pr: Photoreceptor, setup: Setup, step_s: float, *, chunk_steps: int | None = None) -> str:
    """Start ``pr`` at the periodic steady state of the scene's lamps (a sensor that has been running), the
    period's photocurrent made ``chunk_steps`` steps at a time (None: all at once; the result is the same);
    returns what was done, for the file's ``start`` attribute."""
    period = common_period_s(setup.waveforms)
    if period is None:
        return "settled on the first sample: the lamps have no common period <= 0.1 s"
    if period == 0.0:
        period = step_s  # constant light: one step of it is its period
    n = max(1, int(np.ceil(period / step_s - 1e-9)))
    t_end = step_grid(setup.waveforms, 0.0, period / n * np.arange(1, n + 1))
    starts = np.r_[0.0, t_end[:-1]]
    pr.settle(lambda a, b: held_photocurrent(setup, float(starts[a]), t_end[a:b]), np.diff(t_end, prepend=0.0),
              chunk_steps=chunk_steps)
    return f"periodic steady state of the lamps ({period * 1e3:.6g} ms, {len(t_end)} steps)"


def step_grid(waveforms: tuple | list, t_start: float, t_end: np.ndarray) -> np.ndarray:
    """The step ends ``t_end`` with every waveform breakpoint inside them added (a lamp's jump is
    then at a step boundary, so holding each step's mean light is exact for piecewise-constant
    light); breakpoints within 1 ns of a step end are dropped."""
    lo, hi = float(t_start), float(t_end[-1])
    extra = np.concatenate([wf.breakpoints_s(lo, hi) for wf in waveforms] + [np.empty(0)])
    if extra.size == 0:
        return t_end
    extra = np.unique(extra)
    near = np.searchsorted(t_end, extra)
    gap = np.minimum(np.abs(extra - t_end[np.minimum(near, len(t_end) - 1)]),
                     np.abs(extra - t_end[np.maximum(near - 1, 0)]))
    extra = extra[(gap > 1e-9) & (extra - lo > 1e-9)]
    return np.union1d(t_end, extra)


def held_photocurrent(setup: Setup, t_start: float, t_end: np.ndarray) -> np.ndarray:
    """Photocurrent (T, H, W) held over each step (t_end[k - 1], t_end[k]]: the waveforms' exact
    mean over the step, the poses at its middle."""
    starts = np.r_[t_start, t_end[:-1]]
    dt = t_end - starts
    return photocurrent_at(setup, starts + 0.5 * dt, weights_at(setup.waveforms, starts, average_over_s=dt))


def refine(t_end: np.ndarray, t_start: float, k: int) -> np.ndarray:
    """Each step (t_end[i - 1], t_end[i]] split into ``k`` equal sub-steps."""
    if k == 1:
        return t_end
    starts = np.r_[t_start, t_end[:-1]]
    frac = np.arange(1, k + 1) / k
    fine = starts[:, None] + (t_end - starts)[:, None] * frac[None, :]
    fine[:, -1] = t_end  # the configured ends exactly
    return fine.ravel()


def burn_in_span_s(burn_in_s: float, period_s: float | None) -> float:
    """The burn-in actually run: ``burn_in_s`` rounded up to whole lamp periods (so that the light at
    -span is the light at 0), 0 when ``burn_in_s`` is 0."""
    if burn_in_s <= 0.0:
        return 0.0
    if period_s:  # a common lamp period: whole periods
        return math.ceil(burn_in_s / period_s - 1e-9) * period_s
    return float(burn_in_s)


def start_levels(pr: Photoreceptor, emulators: Iterable) -> None:
    """Draw each DVS level of ``emulators`` (those with ``start_from_noise``) from its stationary law given the
    noise of the settled ``pr`` (:meth:`~gevsim.events.BrightnessEmulator.start_from_noise`)."""
    for em in emulators:
        law = pr.output_noise_law(em.params.refractory_s) if hasattr(em, "start_from_noise") else None
        if law is not None:
            em.start_from_noise(*law, signal_ln=pr.settled_ln)


def burn_in(pr: Photoreceptor, emulators: dict, setup: Setup, *, span_s: float, step_s: float, sub: int,
            chunk_steps: int, grid_waveforms: tuple, periodic: bool, bridging: Bridging | None = None) -> None:
    """Run ``pr`` (created with ``t0_s = -span_s`` and settled) and the ``emulators`` over (-span_s, 0] on the
    settled signal, events discarded (each DVS level first drawn from its stationary law given the noise,
    :meth:`~gevsim.events.BrightnessEmulator.start_from_noise`; the burn-in settles what that law leaves out:
    the pixels noisy enough to fire both ways, the gradient comparators, the CSDVS levels): the lamps' light
    (``periodic``: their waveforms, whole periods;
    else held at the first step's) with the poses of t = 0. Each emulator that decodes from a start state
    has it set at t = 0 (``mark_start``). The steps are split at ``grid_waveforms``' jumps (the flicker
    run's lamps: its counterfactuals step, and draw their noise, alike). ``bridging``: the crossing rule's
    noise-free twin, stepped alike (its bridges go to the emulators that take them)."""
    start_levels(pr, emulators.values())
    n_steps = max(1, math.ceil(span_s / step_s - 1e-9))
    grid = span_s / n_steps * np.arange(1, n_steps + 1)  # (0, span]: the burn-in shifted by +span
    first = held_photocurrent(setup, 0.0, grid[:1])  # the held light when not periodic
    for a in range(0, n_steps, chunk_steps):
        b = min(a + chunk_steps, n_steps)
        t0 = float(grid[a - 1]) if a else 0.0
        t_end = refine(grid[a:b], t0, sub)
        if periodic:
            t_end = step_grid(grid_waveforms, t0, t_end)
            starts = np.r_[t0, t_end[:-1]]
            weights = weights_at(setup.waveforms, starts, average_over_s=t_end - starts)
            current = photocurrent_at(setup, np.zeros(len(t_end)), weights)
        else:
            current = np.broadcast_to(first, (len(t_end),) + first.shape[1:])
        t_run = t_end - span_s
        t_run[-1] = 0.0 if b == n_steps else t_run[-1]
        v = pr.process(current, t_run)
        bridge = bridging.bridge(current, t_run) if bridging is not None else None
        for name, em in emulators.items():
            em.process(v, t_run, **process_kwargs(EMULATORS[name].bridges, bridge))
    for em in emulators.values():
        if hasattr(em, "mark_start"):
            em.mark_start()
