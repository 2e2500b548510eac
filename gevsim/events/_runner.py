"""Shared driving of the event kernels: input checks, state, buffers, sorting.

Events of a chunk are ordered by (timestamp, step, block, the kernel's
emission order): this order is the same whether a sequence is processed in
one call or in chunks.
"""

from __future__ import annotations

import numpy as np

from gevsim._validate import real_array
from gevsim.events import _kernels
from gevsim.timebase import check_chunk


class SampledSignal:
    """Time bookkeeping for an emulator fed with samples at increasing times.

    The first sample initialises the state (no events); each later sample ends
    a step that began at the previous one.
    """

    def __init__(self, shape):
        self.shape = tuple(int(s) for s in shape)
        self.t_s: float | None = None

    def steps(self, signal, t_s, *, name: str = "signal"):
        """Validate a chunk; return (signal (T, H, W), step starts, step ends, first-sample flag)."""
        v, t, prev = check_chunk(signal, t_s, shape=self.shape, name=name, after=self.t_s)
        real_array(v, name)
        first = self.t_s is None
        return v, prev, t, first


def run_with_buffers(call, state: tuple, *, nblocks: int, n_steps: int, estimate: int, dtype, width: int):
    """Run ``call(state, buf_t, buf_step, buf_pix, buf_p, buf_axis, count)`` on copies of
    the ``state`` arrays (the kernel mutates them), growing the buffers until nothing
    overflows; return (events sorted, new state)."""
    cap = max(256, int(estimate))
    while True:
        args = tuple(a.copy() for a in state)
        buf_t = np.empty((nblocks, cap), np.int64)
        buf_step = np.empty((nblocks, cap), np.int32)
        buf_pix = np.empty((nblocks, cap), np.int32)
        buf_p = np.empty((nblocks, cap), np.int8)
        buf_axis = np.empty((nblocks, cap), np.uint8)
        count = np.zeros(nblocks, np.int64)
        call(args, buf_t, buf_step, buf_pix, buf_p, buf_axis, count)
        if count.max(initial=0) <= cap:
            break
        cap = int(count.max()) * 4
    n = int(count.sum())
    x, y = np.empty(n, np.int16), np.empty(n, np.int16)
    t, p, axis = np.empty(n, np.int64), np.empty(n, np.int8), np.empty(n, np.uint8)
    if not _kernels.collect(buf_t, buf_step, buf_pix, buf_p, buf_axis, count, n_steps, width, x, y, t, p, axis):
        # Long chunk: the same order by a stable sort of the block-major buffers.
        mask = np.arange(cap)[None, :] < count[:, None]
        order = np.lexsort((buf_step[mask], buf_t[mask]))
        pix = buf_pix[mask][order]
        x[:], y[:], t[:] = pix % width, pix // width, buf_t[mask][order]
        p[:], axis[:] = buf_p[mask][order], buf_axis[mask][order]
    events = np.empty(n, dtype=dtype)
    events["x"], events["y"], events["t"] = x, y, t
    if "axis" in dtype.names:
        events["p"] = p
        events["axis"] = axis
    else:
        events["p"] = p > 0
    return events, args
