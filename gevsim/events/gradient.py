"""Gradient events (Lehtonen et al., "Gradient events: improved acquisition of
visual information in event cameras").

G_X(x, y) = I(x+1, y) - I(x, y) and G_Y(x, y) = I(x, y+1) - I(x, y) (0 in the
last column/row); threshold matrix Theta(x, y) = t_i with i = (x + y) mod n;
ternary gradient T = sgn(G) where |G| >= Theta, else 0; a gradient event is
``EVENT_TABLE[T_prev + 1, T + 1]`` whenever T changes, which is lossless: T is
recovered from T_prev and the event (:func:`decode`). With resolution
compression (RC) G_X is averaged over horizontal pairs (x even, x+1) and G_Y
over vertical pairs, with one comparator per pair at the even position, using
the threshold at that position.

In the physical emulator I is the photoreceptor output in ln units and the
thresholds are ln-unit values; in frame mode I is a [0, 1] grayscale frame and
the paper's thresholds {4, 8, 16}/255 apply.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from gevsim._validate import real, real_list
from gevsim.events import _bridge_gradient, _kernels
from gevsim.events._kernels import EVENT_TABLE
from gevsim.events._runner import EventBlocks, SampledSignal
from gevsim.events.bridge import Bridge
from gevsim.events.types import AXIS_X, AXIS_Y, GRADIENT_DTYPE, check_events, empty, is_gradient

PAPER_THRESHOLDS = (4 / 255, 8 / 255, 16 / 255)
#: Default ln-unit thresholds of the physical emulator: the paper's 1:2:4 ratios, the largest
#: equal to the usual DVS contrast threshold of 0.2 (assumed).
LN_THRESHOLDS = (0.05, 0.1, 0.2)


def threshold_matrix(shape: Sequence[int], thresholds: Sequence[float] = PAPER_THRESHOLDS) -> np.ndarray:
    """Theta(x, y) = thresholds[(x + y) mod n], shape (H, W)."""
    t = np.asarray(real_list(thresholds, "thresholds", positive=True), dtype=np.float64)
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    return t[(x + y) % len(t)]


def gradients(image: np.ndarray, *, rc: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """G_X and G_Y of an (H, W) image (last column/row 0); with ``rc`` the pair means,
    written to both members of each pair (the paper's Eqs. for G^RC)."""
    img = np.asarray(image, dtype=np.float64)
    gx = np.zeros_like(img)
    gy = np.zeros_like(img)
    gx[:, :-1] = img[:, 1:] - img[:, :-1]
    gy[:-1, :] = img[1:, :] - img[:-1, :]
    if rc:
        _check_rc(img.shape)
        gx[:, 0::2] = gx[:, 1::2] = 0.5 * (gx[:, 0::2] + gx[:, 1::2])
        gy[0::2, :] = gy[1::2, :] = 0.5 * (gy[0::2, :] + gy[1::2, :])
    return gx, gy


def ternary(g: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """T = 0 where |G| < Theta, else sgn(G); int8."""
    return np.where(np.abs(g) >= theta, np.sign(g), 0).astype(np.int8)


def encode(t_prev: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Gradient events from previous and current ternary gradients (the paper's Table 1)."""
    return EVENT_TABLE[np.asarray(t_prev, int) + 1, np.asarray(t_new, int) + 1]


def check_ternary_state(state: ArrayLike, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A ternary state (2, H, W) of integers -1, 0, 1 (of ``shape`` (H, W) when given) as int8; ValueError
    otherwise (the decoder indexes its event table with these values)."""
    state = np.asarray(state)
    if state.ndim != 3 or state.shape[0] != 2 or (shape is not None and state.shape[1:] != tuple(shape)):
        want = "(2, H, W)" if shape is None else str((2,) + tuple(shape))
        raise ValueError(f"initial state must have shape {want}, got {state.shape}")
    if state.size and (not np.issubdtype(state.dtype, np.integer) or state.min() < -1 or state.max() > 1):
        raise ValueError("initial state values must be -1, 0 or 1 (a ternary state)")
    return state.astype(np.int8)


def decode(events: np.ndarray, initial: np.ndarray, *, t_us: int | None = None) -> np.ndarray:
    """Ternary state (2, H, W) after applying ``events`` with timestamps <= ``t_us``
    (all when None) to the ``initial`` state (2, H, W)."""
    state = np.array(check_ternary_state(initial), dtype=np.int8, copy=True)
    check_events(events, name="events", shape=(state.shape[1], state.shape[2]))
    if not is_gradient(events):
        raise TypeError("decode needs gradient events (with an axis field)")
    ev = events if t_us is None else events[events["t"] <= t_us]
    # Events are applied in order; a comparator may change several times.
    return _kernels.apply_gradient_events(state, ev["axis"], ev["y"], ev["x"], ev["p"], EVENT_TABLE)


def _check_rc(shape) -> None:
    if shape[0] % 2 or shape[1] % 2:
        raise ValueError(f"resolution compression needs even height and width, got {shape[0]}x{shape[1]}")


class GradientEmulator:
    """Gradient-event emulator over (H, W) pixels, state kept across chunks.

    Parameters
    ----------
    shape : (H, W).
    thresholds_ln : the threshold set t_0 .. t_{n-1}, assigned by (x + y) mod n (or pass ``theta``),
        in the units of the signal: ln photocurrent in the physical mode (frame mode, which feeds
        linear frames as the paper does, passes thresholds in frame units such as 4/255).
    theta : an explicit (H, W) threshold matrix instead.
    mismatch_sigma_ln : per-comparator Gaussian threshold mismatch (same units), drawn with ``rng``.
    rc : resolution compression (H and W even).
    interpolate : timestamps at the interpolated crossing inside a step (physical mode); False
        stamps events with the sample time (frame mode, as in the paper).
    hysteresis_ln : comparator hysteresis (same units): a +-1 state returns to 0 only when
        |G| < Theta - hysteresis_ln. 0 (default) is the paper's definition; a design option
        against noise-induced chatter of comparators sitting near their threshold.
    offset_sigma_ln : sigma of the comparators' input offsets (same units; a fixed pattern drawn
        with ``rng``): comparator (a, y, x) compares G - offset with +-Theta, so an offset moves
        both of its thresholds the same way (a physical comparator's offset, unlike
        ``mismatch_sigma_ln``, which widens or narrows |Theta|). A sensor preset gives it in volts
        (``comparator_offset_v``), divided by n U_T.
    """

    dtype = GRADIENT_DTYPE

    def __init__(self, shape: Sequence[int], *, thresholds_ln: Sequence[float] = LN_THRESHOLDS,
                 theta: ArrayLike | None = None, mismatch_sigma_ln: float = 0.0,
                 rc: bool = False, interpolate: bool = True, hysteresis_ln: float = 0.0,
                 offset_sigma_ln: float = 0.0, rng: np.random.Generator | None = None):
        self.clock = SampledSignal(shape)
        self.shape = self.clock.shape
        if rc:
            _check_rc(self.shape)
        base = threshold_matrix(self.shape, thresholds_ln) if theta is None else np.asarray(theta, np.float64)
        if base.shape != self.shape:
            raise ValueError(f"theta must have shape {self.shape}, got {base.shape}")
        if not np.all(base > 0):
            raise ValueError("theta must be positive everywhere")
        theta2 = np.stack([base, base])
        if mismatch_sigma_ln:
            if not isinstance(rng, np.random.Generator):
                raise TypeError("threshold mismatch needs rng=numpy.random.Generator")
            theta2 = np.maximum(theta2 + mismatch_sigma_ln * rng.standard_normal(theta2.shape), 0.05 * theta2)
        self.theta = theta2  # (2, H, W): comparators of the X and Y axes
        self.offset: np.ndarray = np.zeros_like(theta2)
        if real(offset_sigma_ln, "offset_sigma_ln", low=0.0):
            if not isinstance(rng, np.random.Generator):
                raise TypeError("comparator offsets need rng=numpy.random.Generator")
            self.offset = np.asarray(rng.standard_normal(size=theta2.shape), dtype=np.float64) * offset_sigma_ln
        self.rc = bool(rc)
        self.interpolate = bool(interpolate)
        self.hysteresis = real(hysteresis_ln, "hysteresis_ln", low=0.0, high=float(base.min()), high_open=True)
        self.g_prev = np.zeros((2,) + self.shape)
        self.state = np.zeros((2,) + self.shape, np.int8)
        self.x_last: np.ndarray | None = None  # the noise at the last sample (bridged steps only)
        self.blocks = EventBlocks(self.shape[0], dtype=self.dtype,
                                  first_per_step=self.shape[1] / 4, min_free=self.shape[1], run=8)

    def ternary_of(self, image: np.ndarray) -> np.ndarray:
        """Ternary gradients (2, H, W) of one image with this emulator's thresholds."""
        gx, gy = gradients(image, rc=self.rc)
        gx, gy = gx - self.offset[AXIS_X], gy - self.offset[AXIS_Y]
        t = np.stack([ternary(gx, self.theta[AXIS_X]), ternary(gy, self.theta[AXIS_Y])])
        if self.rc:  # one comparator per pair, at the even position; the odd ones hold 0
            t[AXIS_X, :, 1::2] = 0
            t[AXIS_Y, 1::2, :] = 0
        return t

    @functools.cached_property
    def bridge_key(self) -> np.uint64:
        """Keys the crossing rule's draws: a hash of the comparators' random thresholds and offsets (no draw from
        the rng), taken on the first bridged step only."""
        digest = hashlib.sha256(self.theta.tobytes() + self.offset.tobytes()).digest()
        return np.uint64(int.from_bytes(digest[:8], "little"))

    def mark_start(self) -> None:
        """Take the present ternary state as :attr:`initial_state` (a run's t = 0 after a burn-in)."""
        self.initial_state = self.state.copy()

    def process(self, signal: ArrayLike, t_s: ArrayLike, *, bridge: Bridge | None = None) -> np.ndarray:
        """Events sorted by time from samples ``signal`` (T, H, W) at times ``t_s``.

        The first sample sets the initial ternary state (no events); see
        :attr:`initial_state` to decode from it. With ``bridge`` (:class:`gevsim.events.bridge.Bridge`), a
        comparator may also leave its state and come back between two samples, or cross its level more often
        than once, with the probabilities of :mod:`gevsim.events._bridge_gradient` (long steps; no hysteresis).
        The first bridged step after steps without it takes the noise at its first sample as 0.
        """
        if bridge is not None and self.hysteresis > 0.0:
            raise ValueError(f"the crossing rule needs hysteresis_ln = 0, got {self.hysteresis!r}")
        v, t_start, t_end, first = self.clock.steps(signal, t_s, name="signal")
        if len(t_end) == 0:
            return empty(self.dtype)
        g_prev, state = self.g_prev.copy(), self.state.copy()
        if first:
            gx, gy = gradients(v[0], rc=self.rc)
            g_prev = np.stack([gx, gy]) - self.offset
            state = self.ternary_of(v[0])
            self.initial_state = state.copy()
        steps = v[1:] if first else v
        t_start, t_end = (t_start[1:], t_end[1:]) if first else (t_start, t_end)
        if bridge is None:
            def kernel(a, b, us_end, *bufs_and_region):
                _kernels.gradient(steps[a:b], t_start[a:b], t_end[a:b], us_end, g_prev, state, self.theta, self.offset,
                                  self.hysteresis, self.rc, self.interpolate, EVENT_TABLE, *bufs_and_region)
            self.x_last = None
        else:
            mu, itot = bridge.arrays(v.shape, first)
            mu, itot = mu.reshape(v.shape), itot.reshape(steps.shape)
            x_prev = (v[0].astype(np.float64) - mu[0] if first
                      else (np.zeros(self.shape) if self.x_last is None else self.x_last))
            mu = mu[1:] if first else mu
            law = bridge.law.as_tuple()

            def kernel(a, b, us_end, *bufs_and_region):
                _bridge_gradient.gradient_bridged(steps, mu, itot, x_prev, a, t_start[a:b], t_end[a:b], us_end,
                                                  g_prev, state, self.theta, self.offset, self.rc, self.interpolate,
                                                  EVENT_TABLE, law, self.bridge_key, *bufs_and_region)
            self.x_last = v[-1].astype(np.float64) - mu[-1]
        events = self.blocks.collect(kernel, t_start, t_end)
        self.g_prev, self.state = g_prev, state
        self.clock.t_s = float(np.asarray(t_s, float).reshape(-1)[-1])
        return events
