"""Crossings between the samples of a run's steps (issue 37, item 1): the config's ``crossings`` rule.

``samples`` (the default): the comparators see the signal at the step ends only, linear in between, so the
driver splits each configured step into sub-steps no longer than the sensor's fastest noise path allows
(:func:`gevsim.pixel.noise.coarsest_step_s`, ~20 us for davis346). ``bridge``: the DVS and the gradient
comparators also place the crossings between two samples with the Rice bridge's probability
(:mod:`gevsim.events.bridge`), so a step may be as long as :data:`BRIDGE_MAX_STEP_S`, the longest at which the
noise-event rates were measured to hold (``benchmarks/bridged_dvs.py``: within -2 % to +10 % of the short steps
at 2 ms from 0.1 to 1000 chip lux, static and under a 5 Hz sinusoid; ``benchmarks/gradient_bridge.py``: the
gradient comparators within -2 % to +3 % of 5-us steps up to 5 ms). The rule needs each step's noise-free
signal: a noise-free twin of the photoreceptor (:meth:`gevsim.pixel.Photoreceptor.noise_free_twin`) runs beside
it.
"""

from __future__ import annotations

import numpy as np

from gevsim.events.bridge import Bridge
from gevsim.pixel import Photoreceptor

#: The longest step the bridge rule is validated at (s).
BRIDGE_MAX_STEP_S = 2e-3

#: Crossing rules by config name: the longest step each allows (None: the sensor's coarsest step).
CROSSING_RULES: dict[str, float | None] = {"samples": None, "bridge": BRIDGE_MAX_STEP_S}


class Bridging:
    """The bridge rule's part of a run: the photoreceptor's noise-free twin, stepped beside it, and its law.
    Take it right after the photoreceptor settles (:func:`bridging_for`)."""

    def __init__(self, pr: Photoreceptor):
        law = pr.noise_law()
        if law is None:
            raise ValueError("the bridge rule needs a photoreceptor with an output pole")
        self.law = law
        self.twin = pr.noise_free_twin()
        self.gain = pr.gain.astype(np.float32)
        self.dark_a = pr.dark_a.astype(np.float32)

    def bridge(self, photocurrent_a: np.ndarray, t_s: np.ndarray) -> Bridge:
        """The chunk's bridge: the twin stepped over the same photocurrent (T, H, W) and times, and the total
        photocurrent of each step."""
        current = np.asarray(photocurrent_a, np.float32)
        noise_free = self.twin.process(current, t_s)
        total = current.reshape(len(current), -1) * self.gain + self.dark_a
        return Bridge(noise_free, total.reshape(current.shape), self.law)


def bridging_for(rule: str, pr: Photoreceptor) -> Bridging | None:
    """The run's :class:`Bridging` for crossing rule ``rule``, or None: the ``samples`` rule, or a photoreceptor
    without temporal noise (its signal between two samples is the noise-free path, which the comparators
    already follow as the straight line between them, as with the ``samples`` rule). Raises ValueError for a
    noisy photoreceptor without an output pole (a single pole's noise has no crossing rate)."""
    if rule not in CROSSING_RULES:
        raise ValueError(f"unknown crossing rule {rule!r}; known: {', '.join(CROSSING_RULES)}")
    if CROSSING_RULES[rule] is None:
        return None
    law = pr.noise_law()
    if law is None:
        if pr.shot_q > 0.0 or pr.amp_ln2_hz > 0.0 or pr.n_read:
            raise ValueError(f"crossings = {rule!r} needs a photoreceptor with an output pole (second_pole_hz): "
                             "without one its noise has no crossing rate")
        return None
    if law.shot_q <= 0.0 and law.amp_ln2_hz <= 0.0 and law.read_var_ln2 <= 0.0:
        return None
    return Bridging(pr)


def process_kwargs(bridges: bool, bridge: Bridge | None) -> dict:
    """An emulator's ``process`` keywords: the bridge where the emulator takes one (registry ``bridges``)."""
    return {"bridge": bridge} if bridges and bridge is not None else {}
