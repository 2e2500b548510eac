"""Requests checked before work (issue 24, #11 and #17): memory, disk and run-count estimates of a
command, refused with one :class:`~gevsim.errors.ConfigError` that names the key, the number and the limit.

Limits are physical where they can be: installed memory (``os.sysconf``) and the free space where an
output goes (``shutil.disk_usage``), both from :mod:`gevsim._resources`. Counts that only cost time have
stated caps (:data:`MAX_STUDY_RUNS`, :data:`MAX_SEQUENCES`, :data:`MAX_SPP`). Memory estimates follow
measured peaks and leave out what depends on the data (events), so a refused request could not have
finished; docs/config.md lists them.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

from gevsim import _resources
from gevsim.errors import ConfigError

__all__ = ["MAX_REPEATS", "MAX_SEQUENCES", "MAX_SPP", "MAX_STUDY_RUNS", "EmulationRequest", "at_most",
           "budget_chunk_steps", "check_emulation", "check_export", "check_frame_memory", "check_frame_times",
           "check_render_frames", "check_writable", "chunk_budget_bytes", "fits_disk", "fits_memory", "step_bytes"]

#: The most runs one study sweeps (the product of its axes' lengths); each is an emulation of seconds.
MAX_STUDY_RUNS = 10_000
#: The most noise seeds a study repeats each run with: 1000 seeds already give a 95 % interval about 3 %
#: of the between-seed spread wide (1.96 / sqrt(1000) ~ 0.06 spreads, half-width 0.03), far narrower than any
#: other knob a study sweeps.
MAX_REPEATS = 1000
#: The most sequences one dataset config makes (shard names ``seq_NNNNN`` count them).
MAX_SEQUENCES = 1_000_000
#: The most samples per pixel a render takes (``spp``, ``max_spp``): 64 times the default ``max_spp``.
MAX_SPP = 2**20
#: Bytes a chunk holds per pixel and step: the float64 photocurrent, and 4 more per emulator (measured
#: peaks over a 256-step chunk: 12.4 B with DVS alone, 24.9 B with all four, at 64x48 and 20000 steps a chunk).
CHUNK_BYTES_BASE, CHUNK_BYTES_PER_EMULATOR = 8, 4
#: ... and with ``crossings = "bridge"`` the noise-free signal and the total photocurrent (float32 each).
CHUNK_BYTES_BRIDGE = 8
#: A run's chunks, unless its config sets ``chunk_steps``, take this share of the memory the process may use
#: (:func:`gevsim._resources.usable_memory`: installed memory, or ``ulimit -v`` where lower) ...
CHUNK_MEMORY_FRACTION = 1 / 16
#: ... and at most this much on any machine: 11 million pixel-steps with all four emulators, 12 steps at 1280x720,
#: which step as fast as 48 or 256 (benchmarks/memory_chunks.py); a 1280x720 run of office peaks at 1.4 GB whatever
#: its duration (5.9 GB with 256-step chunks).
CHUNK_MEMORY_CAP_BYTES = 256 * 2**20
#: The most steps a chunk sized to the budget takes (the former fixed ``chunk_steps``).
MAX_CHUNK_STEPS = 256
#: Bytes per step of a whole run (its float64 step ends) and per millisecond and stream (the int64
#: ``ms_to_idx`` index every event file carries, built in memory when the file is closed).
STEP_BYTES, MS_BYTES = 8, 8
#: Frame mode holds four float64 copies of its frames (read, stacked, their log, the emulators' work):
#: 35.6 bytes a pixel measured with six 2000x2000 frames that make few events.
FRAME_PX_BYTES = 32
#: An AEDAT4 event takes at most 16 bytes (dv-processing's packed event), and LZ4 adds at most 1 % to
#: data it cannot compress; 64 KiB more for the header and index.
AEDAT4_EVENT_BYTES = 16


class EmulationRequest(Protocol):
    """What :func:`check_emulation` reads of a run's config (an ``EmulationConfig`` has it): the
    time step, the steps of a chunk, the emulators and where the config came from."""

    @property
    def step_s(self) -> float: ...

    @property
    def chunk_steps(self) -> int | None: ...

    @property
    def emulators(self) -> Sequence[str]: ...

    @property
    def source(self) -> str | None: ...


def fits_memory(need: float, *, what: str, source: str | None, key: str | None, hint: str = "") -> None:
    """Refuse ``need`` bytes of memory over this machine's installed memory."""
    have, phrase = _resources.usable_memory()
    if have is not None and need > have:
        raise ConfigError(f"{what} need about {_resources.gib(need)} of memory; {phrase} "
                          f"{_resources.gib(have)}{hint}", source=source, key=key)


def fits_disk(need: float, where: str | os.PathLike, *, what: str, source: str | None, key: str | None,
              hint: str = "") -> None:
    """Refuse ``need`` bytes over the free space of the file system that ``where`` goes to."""
    free = _resources.free_disk_bytes(where)
    if free is not None and need > free:
        raise ConfigError(f"{what} take up to {_resources.gib(need)}; {_resources.gib(free)} are free where "
                          f"{where} goes{hint}", source=source, key=key)


def at_most(n: float, limit: float, *, what: str, source: str | None, key: str | None, hint: str = "") -> None:
    """Refuse a count ``n`` over its stated cap ``limit``: "<what> is <n>; at most <limit> are allowed"."""
    if n > limit:
        raise ConfigError(f"{what} is {n:.6g}; at most {limit:.6g} are allowed{hint}", source=source, key=key)


def check_writable(out: str | os.PathLike, *, inside: bool = False) -> None:
    """Refuse, before any work, an output that cannot be written: a probe file (unnamed where the system
    allows) is made in the folder that will hold ``out`` (``inside``: in ``out`` itself when it is a
    folder), or in its nearest existing parent, which gevsim would create the rest below."""
    out = Path(out)
    folder = out if inside and out.is_dir() else out.parent
    folder = Path(os.path.abspath(folder))
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    try:
        with tempfile.TemporaryFile(dir=folder, prefix=".gevsim-probe-"):
            pass
    except OSError as exc:
        raise ConfigError(f"cannot write here ({exc.strerror or exc}); choose another output", source=str(out)) \
            from None


def chunk_budget_bytes() -> int:
    """The memory a run's chunk may take unless its config sets ``chunk_steps``: :data:`CHUNK_MEMORY_FRACTION` of
    what the process may use (:func:`gevsim._resources.usable_memory`), at most :data:`CHUNK_MEMORY_CAP_BYTES`."""
    have, _ = _resources.usable_memory()
    return CHUNK_MEMORY_CAP_BYTES if have is None else int(min(have * CHUNK_MEMORY_FRACTION, CHUNK_MEMORY_CAP_BYTES))


def step_bytes(*, width: int, height: int, emulators: int, substeps: int = 1, bridge: bool = False) -> int:
    """Bytes one step of a chunk holds (:data:`CHUNK_BYTES_BASE` and :data:`CHUNK_BYTES_PER_EMULATOR` a pixel and
    sub-step, and :data:`CHUNK_BYTES_BRIDGE` with the bridge rule)."""
    per_px = CHUNK_BYTES_BASE + CHUNK_BYTES_PER_EMULATOR * int(emulators) + (CHUNK_BYTES_BRIDGE if bridge else 0)
    return int(width) * int(height) * int(substeps) * per_px


def _bridged(config: EmulationRequest) -> bool:
    return getattr(config, "crossings", "samples") != "samples"


def budget_chunk_steps(config: EmulationRequest, *, width: int, height: int, substeps: int = 1) -> int:
    """The steps of a chunk: ``config.chunk_steps`` where it sets one, else as many as fit
    :func:`chunk_budget_bytes`, at least 1 and at most :data:`MAX_CHUNK_STEPS` (chunks bound memory, not results)."""
    if config.chunk_steps is not None:
        return int(config.chunk_steps)
    per_step = step_bytes(width=width, height=height, emulators=len(config.emulators), substeps=substeps,
                          bridge=_bridged(config))
    return max(1, min(MAX_CHUNK_STEPS, chunk_budget_bytes() // max(per_step, 1)))


def check_emulation(config: EmulationRequest, *, width: int, height: int, duration_s: float,
                    substeps: int = 1) -> None:
    """Memory of an emulation of ``config`` (an :class:`EmulationRequest`) at ``width`` x ``height`` px: one chunk
    (``chunk_steps``, or the budget's: :func:`budget_chunk_steps`) and the whole run's time grid and millisecond
    index (the duration and ``step_s``), each step split into ``substeps`` (known once the basis is rendered: the
    sensor's fastest noise path)."""
    steps = duration_s / config.step_s * substeps
    chunk_steps = budget_chunk_steps(config, width=width, height=height, substeps=substeps)
    chunk = min(chunk_steps * substeps, steps) * step_bytes(width=width, height=height,
                                                            emulators=len(config.emulators), bridge=_bridged(config))
    split = f" split into {substeps} sub-steps each" if substeps > 1 else ""
    size = f"{width}x{height} px x {len(config.emulators)} emulators"
    if config.chunk_steps is not None:
        fits_memory(chunk, what=f"chunks of {config.chunk_steps} steps{split} x {size}", source=config.source,
                    key="emulation.chunk_steps", hint=": lower chunk_steps (it bounds memory, not results)")
    else:  # the budget's chunk: over memory only when one step is
        fits_memory(chunk, what=f"one step{split} x {size}", source=config.source, key="emulation.step_s",
                    hint=": a chunk holds at least one step" + (": shorten step_s (fewer sub-steps)" if split else ""))
    whole = steps * STEP_BYTES + (duration_s * 1e3 + 1) * MS_BYTES * len(config.emulators)
    fits_memory(whole, what=f"{steps:.4g} steps (duration_s = {duration_s:g} over step_s = {config.step_s:g}"
                            f"{split})", source=config.source, key="emulation.duration_s",
                hint=": shorten the duration or lengthen step_s" if substeps == 1 else ": shorten the duration")


def check_render_frames(rate_hz: float, duration_s: float, *, width: int, height: int, channels: int,
                        out: str | os.PathLike) -> None:
    """``render --frames``: at most :data:`~gevsim.timebase.MAX_FRAMES` frames; the float32 irradiance frames
    held in memory (with the float64 radiance they are mixed from) and written as EXR (ZIP, at most raw size)."""
    from gevsim.timebase import MAX_FRAMES

    product = rate_hz * duration_s
    n_frames = math.ceil(product - 1e-9) if math.isfinite(product) else math.inf
    at_most(n_frames, MAX_FRAMES, what=f"--frames {rate_hz:g} over the scene's {duration_s:g} s: the frame count",
            source="command line", key="--frames")
    raw = n_frames * int(width) * int(height) * channels * 4
    fits_memory(3 * raw, what=f"{n_frames} frames of {width}x{height} px", source="command line", key="--frames")
    fits_disk(raw, out, what=f"{n_frames} frames of {width}x{height} px", source="command line", key="--frames")


def check_frame_memory(n_frames: int, shape: tuple[int, ...], *, source: str | None) -> None:
    """Frame mode: :data:`FRAME_PX_BYTES` per pixel of every frame, before the frames are read."""
    h, w = shape[-2:]
    fits_memory(n_frames * h * w * FRAME_PX_BYTES, what=f"{n_frames} frames of {w}x{h} px", source=source, key=None,
                hint=": use fewer or smaller frames")


def check_frame_times(last_t_s: float, *, source: str | None) -> None:
    """Frame mode: the event file's millisecond index (per stream) up to the last frame time."""
    fits_memory((last_t_s * 1e3 + 1) * MS_BYTES * 3, what=f"frame times up to {last_t_s:.6g} s (a millisecond "
                                                          "index per stream)", source=source, key="timestamps")


def check_export(counts: int, out: str | os.PathLike, *, source: str) -> None:
    """AEDAT4 export: ``counts`` events at most :data:`AEDAT4_EVENT_BYTES` each, against the free space
    where ``out`` goes (dv-processing aborts the process on a full disk, so this is checked first)."""
    fits_disk(counts * AEDAT4_EVENT_BYTES * 1.01 + (1 << 16), out, what=f"{counts} events in AEDAT4", source=source,
              key=None)
