"""Optics: scene radiance -> focal-plane irradiance -> photocurrent.

Rendered values are "photopic-equivalent radiance" in W/(m^2 sr): their
luminance Y times 683 lm/W is the luminance in cd/m^2. The lens turns them
into focal-plane irradiance (camera equation), the pixel into photocurrent
through the lamp spectrum, the pixel area and the silicon QE.
"""

from gevsim.optics.lens import Lens, cos4_map, field_angle_map, focal_plane_irradiance
from gevsim.optics.photocurrent import (
    group_photocurrent_factors,
    photocurrent_a,
    responsivity_a_per_lm,
)
from gevsim.optics.photometry import (
    K_M_LM_PER_W,
    REC709_LUMA_WEIGHTS,
    illuminance_lux,
    lamp_names,
    lamp_spectrum,
    luminance,
    luminous_efficacy_lm_per_w,
    photopic_lef,
    spectrum_to_rgb,
)
from gevsim.optics.sensor import (
    QE_CURVES,
    SILICON_QE_BSI,
    SILICON_QE_FSI,
    Pixel,
    quantum_efficiency,
    silicon_qe,
    silicon_qe_sd,
)
from gevsim.optics.spec import OPTICS_KEYS, from_spec

__all__ = [
    "K_M_LM_PER_W",
    "OPTICS_KEYS",
    "REC709_LUMA_WEIGHTS",
    "QE_CURVES",
    "SILICON_QE_BSI",
    "SILICON_QE_FSI",
    "Lens",
    "Pixel",
    "cos4_map",
    "field_angle_map",
    "focal_plane_irradiance",
    "from_spec",
    "group_photocurrent_factors",
    "illuminance_lux",
    "lamp_names",
    "lamp_spectrum",
    "luminance",
    "luminous_efficacy_lm_per_w",
    "photocurrent_a",
    "photopic_lef",
    "quantum_efficiency",
    "responsivity_a_per_lm",
    "silicon_qe",
    "silicon_qe_sd",
    "spectrum_to_rgb",
]
