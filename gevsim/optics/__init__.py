"""Optics: scene radiance -> focal-plane irradiance -> photocurrent.

Rendered values are "photopic-equivalent radiance" in W/(m^2 sr): their
luminance Y times 683 lm/W is the luminance in cd/m^2. The lens turns them
into focal-plane irradiance (camera equation), the pixel into photocurrent
through the lamp spectrum, the pixel area and the silicon QE.

The names below are imported on first use (:mod:`gevsim._lazy`): a scene manifest checks its lamp
names (:data:`gevsim.optics.lamps.LAMP_NAMES`) without importing colour-science.
"""

from gevsim._lazy import attach

TYPE_CHECKING = False
if TYPE_CHECKING:
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
    from gevsim.optics.qe_curves import QE_CURVES, SILICON_QE_BSI, SILICON_QE_FSI
    from gevsim.optics.sensor import (
        Pixel,
        quantum_efficiency,
        silicon_qe,
        silicon_qe_sd,
    )
    from gevsim.optics.spec import OPTICS_KEYS, from_spec

__getattr__, __dir__ = attach(__name__, {
    **dict.fromkeys(("Lens", "cos4_map", "field_angle_map", "focal_plane_irradiance"), "lens"),
    **dict.fromkeys(("group_photocurrent_factors", "photocurrent_a", "responsivity_a_per_lm"), "photocurrent"),
    **dict.fromkeys(("K_M_LM_PER_W", "REC709_LUMA_WEIGHTS", "illuminance_lux", "lamp_names", "lamp_spectrum",
                     "luminance", "luminous_efficacy_lm_per_w", "photopic_lef", "spectrum_to_rgb"), "photometry"),
    **dict.fromkeys(("QE_CURVES", "SILICON_QE_BSI", "SILICON_QE_FSI"), "qe_curves"),
    **dict.fromkeys(("Pixel", "quantum_efficiency", "silicon_qe", "silicon_qe_sd"), "sensor"),
    "OPTICS_KEYS": "spec", "from_spec": "spec",
})

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
