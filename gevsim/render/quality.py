"""Render settings (a manifest's ``[render]`` table): resolution, sampling and the
noise-target quality mode, their keys and their checking.

Scene manifests (:mod:`gevsim.render.manifest`) read them; emulation, study and
dataset configs may override a subset (:data:`OVERRIDE_KEYS`, checked by
:func:`check_render_overrides`); the renderer (:mod:`gevsim.render.basis`)
resolves the noise target with :func:`resolve_target`.
"""

from __future__ import annotations

from dataclasses import dataclass

from gevsim.config import TomlReader
from gevsim.errors import check_keys, suggest
from gevsim.render.backend import FLAVOURS
from gevsim.render.convergence import METRICS as NOISE_METRICS
from gevsim.resources import MAX_SPP

#: The keys of the noise-target mode (:class:`RenderSettings`).
QUALITY_KEYS = ("noise_target_ln", "noise_percentile", "max_spp", "time_budget_s", "sampler", "noise_floor_rel",
                "noise_metric", "denoise", "reuse", "sampling")
#: Every ``[render]`` key of a scene manifest.
RENDER_KEYS = ("width", "height", "spp", "seed", "flavour", "max_depth", "max_px_per_pose") + QUALITY_KEYS
#: ``[render]`` keys that emulation, study and dataset configs may override.
OVERRIDE_KEYS = ("width", "height", "spp", "seed", "max_px_per_pose") + QUALITY_KEYS
#: Mitsuba samplers a scene may use (``[render] sampler``).
SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")
#: How a moving scene's poses get their images (``[render] reuse``, :mod:`gevsim.render.poses`): ``"none"``
#: renders every pose alone; ``"rotation"`` resamples a camera turning about a fixed centre from one wider
#: render (:mod:`gevsim.render.rotation`); ``"auto"`` takes the first that applies.
REUSE = ("auto", "none", "rotation", "parallax")
#: How a noise-target render spends samples (``[render] sampling``): ``"uniform"``, every pixel alike until
#: the stop rule holds; ``"adaptive"``, after the first batches only pixels whose error is above
#: :data:`gevsim.render.pose_render.ADAPTIVE_STOP_FRACTION` x the target (Manabe et al., ICCP 2024, per-pixel tests).
SAMPLING = ("uniform", "adaptive")
#: ``noise_target_ln = "auto"``: this fraction of the smallest event threshold. Measured on the office
#: (128x96, ideal sensor, benchmarks/flicker_convergence.py): at a p99 flicker-metric error of 0.4 x 0.05 ln
#: (~9000 spp) the flicker-induced gradient rate is +3.7 % and +8.3 % (two seeds) above a 65536-spp reference,
#: and halving the target (~35000 spp) changes it by -2.5 % and -6.5 %; DVS moves by < 0.3 %. The issue's
#: first guess, 0.1 x, would need ~500k spp (p99 falls as 1/sqrt(spp): 0.0070 at 65536).
AUTO_TARGET_FRACTION = 0.4
#: ... which, when rendering without a sensor, is this (ln units; a typical gradient threshold).
DEFAULT_THRESHOLD_LN = 0.05

__all__ = [
    "AUTO_TARGET_FRACTION",
    "DEFAULT_THRESHOLD_LN",
    "NOISE_METRICS",
    "OVERRIDE_KEYS",
    "QUALITY_KEYS",
    "RENDER_KEYS",
    "REUSE",
    "SAMPLERS",
    "SAMPLING",
    "RenderSettings",
    "check_render_overrides",
    "quality_settings",
    "render_settings",
    "resolve_target",
]


@dataclass(frozen=True)
class RenderSettings:
    """How a scene is rendered.

    Two modes. *Fixed*: ``spp`` samples per pixel (drafts). *Noise target*
    (when ``noise_target_ln`` is set): render in independent batches until the
    ``noise_percentile`` percentile over pixels of the standard error of
    ln(luminance), for the lamp mixtures the waveforms reach, is at most
    ``noise_target_ln``, or ``max_spp`` / ``time_budget_s`` is reached (see
    :mod:`gevsim.render.convergence`). ``noise_target_ln = "auto"`` is 0.4 x
    the smallest event threshold of the sensor an emulation uses (0.4 x 0.05 ln
    when rendering alone; the fraction is measured, see ``AUTO_TARGET_FRACTION``).
    ``noise_floor_rel`` keeps near-black pixels from dominating: the error is
    taken relative to (value + noise_floor_rel x the mixture's mean).
    ``noise_metric`` chooses the error measured: of the change of ln luminance
    between lamp mixtures (``"flicker"``, default) or of ln luminance itself
    (``"absolute"``). ``denoise = true`` passes the finished group images
    through Intel Open Image Denoise (:mod:`gevsim.render.denoise`): biased,
    off by default; its bias is measured in ``benchmarks/README.md``.
    ``reuse`` chooses how the poses of a moving scene are rendered (:data:`REUSE`), ``sampling``
    how a noise-target render spends its samples over pixels (:data:`SAMPLING`).
    """

    width: int = 346
    height: int = 260
    spp: int = 16
    seed: int = 0
    flavour: str = "rgb"
    max_depth: int = 5
    max_px_per_pose: float = 1.0
    noise_target_ln: float | str | None = None
    noise_percentile: float = 99.0
    max_spp: int = 16384
    time_budget_s: float | None = None
    sampler: str = "multijitter"
    noise_floor_rel: float = 1e-3
    noise_metric: str = "flicker"
    denoise: bool = False
    reuse: str = "auto"
    sampling: str = "uniform"

    @property
    def targeted(self) -> bool:
        """Whether this is the noise-target mode (else a fixed ``spp``)."""
        return self.noise_target_ln is not None


#: The largest render gevsim accepts, in pixels per image: 8K UHD (7680 x 4320) fits; event sensors have about
#: 1 Mpx at most. Every basis image is held in memory (float32 RGB, with its noise sample: 24 bytes a pixel).
MAX_RENDER_PX = 2**25


def check_render_size(width: int, height: int, r: TomlReader, where: str) -> None:
    """Refuse a render larger than :data:`MAX_RENDER_PX`, naming the key and the numbers."""
    px = int(width) * int(height)
    if px > MAX_RENDER_PX:
        from gevsim._resources import gib

        r.fail(f"{where}.width", f"a {width}x{height} render is {px / 1e6:.4g} Mpx ({gib(24 * px)} per light group "
                                 f"and pose in memory); gevsim renders at most {MAX_RENDER_PX / 1e6:.4g} Mpx "
                                 "(8K UHD, 7680x4320, fits)")


def render_settings(table: dict, r: TomlReader, where: str = "render") -> RenderSettings:
    """A manifest's ``[render]`` table as :class:`RenderSettings` (errors name the key)."""
    check_keys(table, RENDER_KEYS, source=r.source, where=where)
    d = RenderSettings()
    settings = RenderSettings(
        width=r.number(table, "width", where, d.width, positive=True, integer=True),
        height=r.number(table, "height", where, d.height, positive=True, integer=True),
        spp=r.number(table, "spp", where, d.spp, positive=True, integer=True, maximum=MAX_SPP),
        seed=r.number(table, "seed", where, d.seed, minimum=0, integer=True),
        flavour=str(table.get("flavour", d.flavour)),
        max_depth=r.number(table, "max_depth", where, d.max_depth, positive=True, integer=True),
        max_px_per_pose=float(r.number(table, "max_px_per_pose", where, d.max_px_per_pose, positive=True)),
        **quality_settings(table, r, where),
    )
    if settings.flavour not in FLAVOURS:
        r.fail(f"{where}.flavour", f"expected 'rgb', 'mono' or 'spectral', got {settings.flavour!r}")
    check_render_size(settings.width, settings.height, r, where)
    return settings


def check_render_overrides(table: dict, r: TomlReader, where: str) -> None:
    """Validate a ``[render]`` override table of an emulation, study or dataset config."""
    check_keys(table, OVERRIDE_KEYS, source=r.source, where=where)
    for key in ("width", "height", "spp"):
        if key in table:
            r.number(table, key, where, positive=True, integer=True, maximum=MAX_SPP if key == "spp" else None)
    check_render_size(table.get("width", 1), table.get("height", 1), r, where)
    if "seed" in table:
        r.number(table, "seed", where, minimum=0, integer=True)
    if "max_px_per_pose" in table:
        r.number(table, "max_px_per_pose", where, positive=True)
    quality_settings(table, r, where)


def quality_settings(table: dict, r: TomlReader, where: str) -> dict:
    """The render-quality keys of a ``[render]`` table, validated (errors name the key)."""
    out = {}
    if "spp" in table and "noise_target_ln" in table:
        r.fail(f"{where}.spp", "give either spp (a fixed sample count, for drafts) or noise_target_ln "
                               "(render until the noise target is met), not both")
    if "noise_target_ln" in table:
        target = table["noise_target_ln"]
        if target != "auto":
            target = float(r.number(table, "noise_target_ln", where, positive=True))
        out["noise_target_ln"] = target
    if "noise_percentile" in table:
        p = float(r.number(table, "noise_percentile", where, positive=True))
        if p > 100:
            r.fail(f"{where}.noise_percentile", f"must be in (0, 100], got {p!r}")
        out["noise_percentile"] = p
    if "max_spp" in table:
        out["max_spp"] = r.number(table, "max_spp", where, minimum=1, integer=True, maximum=MAX_SPP)
    if "time_budget_s" in table:
        out["time_budget_s"] = float(r.number(table, "time_budget_s", where, positive=True))
    if "noise_floor_rel" in table:
        out["noise_floor_rel"] = float(r.number(table, "noise_floor_rel", where, positive=True))
    if "denoise" in table:
        if not isinstance(table["denoise"], bool):
            r.fail(f"{where}.denoise", f"expected true or false, got {table['denoise']!r}")
        out["denoise"] = table["denoise"]
    for key, what, options in (("noise_metric", "noise metric", NOISE_METRICS), ("sampler", "sampler", SAMPLERS),
                               ("reuse", "reuse method", REUSE), ("sampling", "sampling", SAMPLING)):
        if key in table:
            value = table[key]
            if value not in options:
                r.fail(f"{where}.{key}", f"unknown {what} {value!r}{suggest(str(value), options)}; "
                                         f"one of {', '.join(options)}")
            out[key] = value
    return out


def resolve_target(settings: RenderSettings, smallest_threshold_ln: float | None = None) -> float | None:
    """The noise target in ln units (None in fixed mode); ``"auto"`` is 0.4 x the smallest event threshold."""
    if settings.noise_target_ln is None:
        return None
    if settings.noise_target_ln == "auto":
        return AUTO_TARGET_FRACTION * (smallest_threshold_ln or DEFAULT_THRESHOLD_LN)
    return float(settings.noise_target_ln)
