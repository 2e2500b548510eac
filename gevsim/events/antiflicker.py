"""On-chip anti-flicker filter (Prophesee ESP "AFK", an IMX636 option): documented behaviour.

Prophesee's ESP documentation: the filter "detects and cancels flicker events in 4x4 divided pixel
regions", for flicker periods of 2 to 20 ms (50 to 500 Hz). The detector's internals are not published;
this module implements that behaviour with stated, assumed rules:

- each block of :data:`BLOCK_PX` x :data:`BLOCK_PX` pixels notes its *rises*: an ON event after an OFF event
  in the block (a lamp's brightening edge);
- the interval between successive rises is a period candidate when it lies in [1 / ``anti_flicker_max_hz``,
  1 / ``anti_flicker_min_hz``]; ``anti_flicker_cycles`` successive candidates within ``anti_flicker_tolerance``
  (relative) of each other mark the block flickering (the readout's parameters, :class:`ReadoutParams`);
- a flickering block's events are dropped until no rise comes for two periods; a rise outside the band or
  off the period ends the streak.

Events must come in time order; the block states carry across calls, so results do not depend on chunks.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from gevsim.pixel.params import ReadoutParams

#: Pixels per block side (Prophesee's ESP docs: "4x4 divided pixel regions").
BLOCK_PX = 4


@njit(cache=True)
def _filter(t, x, y, on, blocks_x, block, lo_us, hi_us, tol, cycles, last_pol, last_rise, period, streak, keep):
    """Walk events in time order; per block: last polarity (-1 none, 0 OFF, 1 ON), last rise (us),
    current period (us) and streak; keep[i] False for events of flickering blocks. Returns the drops."""
    dropped = 0
    for i in range(t.shape[0]):
        b = (y[i] // block) * blocks_x + x[i] // block
        ti = np.float64(t[i])
        if on[i] and last_pol[b] == 0:  # a rise
            p = ti - last_rise[b]
            if lo_us <= p <= hi_us:  # a period candidate: the streak goes on if it repeats the last one
                streak[b] = streak[b] + 1 if streak[b] > 0 and abs(p - period[b]) <= tol * period[b] else 1
            else:
                streak[b] = 0
            period[b] = p
            last_rise[b] = ti
        last_pol[b] = 1 if on[i] else 0
        flickering = streak[b] >= cycles and ti - last_rise[b] <= 2.0 * period[b]
        keep[i] = not flickering
        dropped += flickering
    return dropped


class AntiFlicker:
    """Stateful anti-flicker filter over an (H, W) array (see the module docstring)."""

    def __init__(self, shape: tuple[int, int], params: ReadoutParams):
        self.params = params
        h, w = shape
        self.blocks_x = -(-w // BLOCK_PX)
        n = self.blocks_x * -(-h // BLOCK_PX)
        self.last_pol = np.full(n, -1, np.int8)
        self.last_rise = np.full(n, -np.inf)
        self.period = np.zeros(n)
        self.streak = np.zeros(n, np.int64)
        self.dropped = 0

    def process(self, events: np.ndarray) -> np.ndarray:
        """The events (time order) less those of blocks flagged flickering."""
        if len(events) == 0:
            return events
        p = self.params
        keep = np.empty(len(events), np.bool_)
        on = np.asarray(events["p"]).astype(np.int8) > 0
        self.dropped += int(_filter(events["t"], events["x"].astype(np.int64), events["y"].astype(np.int64), on,
                                    self.blocks_x, BLOCK_PX, 1e6 / p.anti_flicker_max_hz, 1e6 / p.anti_flicker_min_hz,
                                    p.anti_flicker_tolerance, p.anti_flicker_cycles, self.last_pol, self.last_rise,
                                    self.period, self.streak, keep))
        return events[keep]
