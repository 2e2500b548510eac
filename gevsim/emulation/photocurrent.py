"""A run's photocurrent basis (:class:`Setup`) and the photocurrent it gives at any time.

Photocurrent is linear in each light group's radiance, so the driver
(:mod:`gevsim.emulation.driver`) turns each group's basis image into a photocurrent
basis once; the photocurrent at time t is ``sum_k w_k(t) C_k(pose(t))``
(:func:`photocurrent_at`). The driver and the ground truth (:mod:`gevsim.emulation.truth`)
both read it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from gevsim.illumination import mix_poses
from gevsim.pixel.presets import SensorPreset
from gevsim.render import MitsubaScene, SceneManifest, VariantChoice


@dataclasses.dataclass
class Setup:
    """Everything a run needs before its time loop."""

    manifest: SceneManifest
    preset: SensorPreset
    basis_times_s: np.ndarray
    current_basis: np.ndarray  # (P, K, H, W) photocurrent per unit waveform, A
    waveforms: tuple
    duration_s: float
    variant: VariantChoice
    current_noise: np.ndarray | None = None  # (P, K, H, W): the render's error sample in photocurrent
    render_quality: dict = dataclasses.field(default_factory=dict)  # achieved render noise (summarize_quality)
    chip_lux_per_a: np.ndarray | None = None  # (K,): illuminance on the chip per ampere of each group's photocurrent
    scene: MitsubaScene | None = None  # for the geometric ground truth (depth, flow, poses) at frame times


def photocurrent_at(setup: Setup, t_s: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Photocurrent (T, H, W) for waveform weights (T, K) at times t_s: E(t) of
    :func:`~gevsim.illumination.mix_poses` on the photocurrent basis."""
    return mix_poses(setup.current_basis, setup.basis_times_s, t_s, weights)
