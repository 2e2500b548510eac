"""The silicon quantum-efficiency curves a sensor preset names (``[sensor] quantum_efficiency``), as plain
tuples: reading a preset needs them, not colour-science or scipy (:mod:`gevsim.optics.sensor` uses them)."""

#: (wavelength_nm, QE) of a generic FSI CMOS pixel (assumed, typical values).
SILICON_QE_FSI = (
    (300.0, 350.0, 400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0,
     750.0, 800.0, 850.0, 900.0, 950.0, 1000.0, 1050.0, 1100.0),
    (0.0, 0.05, 0.22, 0.40, 0.52, 0.58, 0.57, 0.52, 0.44,
     0.35, 0.26, 0.18, 0.11, 0.06, 0.025, 0.007, 0.0),
)

#: (wavelength_nm, QE) of a generic back-side illuminated (BSI) CMOS pixel (assumed, typical values,
#: shaped after EMVA 1288 reports of BSI sensors): no gate stack in the light path, so higher in the
#: blue and a maximum of ~0.80 at 500-550 nm, the same silicon cut-off in the infrared.
SILICON_QE_BSI = (
    (300.0, 350.0, 400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0,
     750.0, 800.0, 850.0, 900.0, 950.0, 1000.0, 1050.0, 1100.0),
    (0.0, 0.25, 0.55, 0.72, 0.80, 0.80, 0.75, 0.66, 0.55,
     0.43, 0.32, 0.22, 0.14, 0.08, 0.035, 0.01, 0.0),
)

#: QE curves by the name a sensor preset gives (``[sensor] quantum_efficiency``).
QE_CURVES = {"fsi": SILICON_QE_FSI, "bsi": SILICON_QE_BSI}
