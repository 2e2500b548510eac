"""The registries of emulators and reconstruction methods: consistent, and errors that name the value."""

import numpy as np
import pytest

from gevsim.emulation.emulators import (
    APS_READ_SEED,
    APS_SEED,
    EMULATORS,
    FRAME_EMULATORS,
    PHOTORECEPTOR_SEED,
    READOUT_SEED,
    SEED_SLOTS,
    STREAMS,
    check_emulator,
)
from gevsim.evaluation.methods import METHODS, check_method


def test_seed_slots_are_distinct_and_fixed():
    slots = [e.seed_slot for e in EMULATORS.values()] + [PHOTORECEPTOR_SEED, APS_SEED, APS_READ_SEED, READOUT_SEED]
    assert sorted(slots) == list(range(SEED_SLOTS))
    # The slots earlier runs were seeded with: changing one changes every run's events.
    assert {n: e.seed_slot for n, e in EMULATORS.items()} == {"dvs": 1, "gradient": 2, "gradient_rc": 3, "csdvs": 4}


def test_streams_are_distinct_and_frame_mode_runs_a_subset():
    assert len(set(STREAMS.values())) == len(STREAMS)
    assert STREAMS == {n: e.stream for n, e in EMULATORS.items()}
    assert set(FRAME_EMULATORS) <= set(EMULATORS) and "csdvs" not in FRAME_EMULATORS


def test_every_method_reads_a_registered_emulator():
    for method in METHODS.values():
        assert method.emulator in EMULATORS
        assert method.stream == EMULATORS[method.emulator].stream
    assert METHODS["dct_rc"].emulator == "gradient_rc" and METHODS["complementary"].needs_aps


def test_unknown_names_are_named_with_a_suggestion():
    with pytest.raises(ValueError, match="unknown emulator 'gradiant' \\(did you mean 'gradient'\\?\\)"):
        check_emulator("gradiant")
    with pytest.raises(ValueError, match="choose from dvs, gradient, gradient_rc$"):
        check_emulator("csdvs", FRAME_EMULATORS)
    with pytest.raises(ValueError, match="unknown reconstruction method 'dct_cr' \\(did you mean 'dct_rc'\\?\\)"):
        check_method("dct_cr")
    assert check_method("sor_rc") is METHODS["sor_rc"]


def test_make_emulator_builds_from_config_and_preset():
    from gevsim.emulation import EmulationConfig
    from gevsim.emulation.emulators import make_emulator
    from gevsim.pixel import load_preset

    config = EmulationConfig(scene="office", thresholds_ln=(0.1, 0.2), hysteresis_ln=0.01)
    em = make_emulator("gradient_rc", (4, 6), config=config, preset=load_preset("davis346"),
                       rng=np.random.default_rng(0))
    assert em.theta.shape[1:] == (4, 6)
    assert EMULATORS["gradient_rc"].thresholds(em, None).dtype == np.float32


def test_each_emulator_owns_its_parameters_table():
    import dataclasses

    from gevsim.config import FromTable
    from gevsim.emulation import EmulationConfig
    from gevsim.emulation.config import TABLES
    from gevsim.emulation.emulators import PARAMS, GradientConfig, SurroundConfig

    assert PARAMS == (GradientConfig, SurroundConfig)
    assert {n: e.params for n, e in EMULATORS.items()} == {"dvs": None, "gradient": GradientConfig,
                                                           "gradient_rc": GradientConfig, "csdvs": SurroundConfig}
    assert TABLES == ("emulation", "render", "gradient", "csdvs", "light", "sensor")  # the file format
    config = EmulationConfig(scene="office")
    for cls in PARAMS:  # the config's flat fields default to the dataclass's, which is valid
        assert issubclass(cls, FromTable) and config.params(cls) == cls()
        for f in dataclasses.fields(cls):
            assert getattr(config, f.name) == f.default
    assert GradientConfig().thresholds_ln == (0.05, 0.1, 0.2)  # gevsim.events.gradient.LN_THRESHOLDS


def test_parameter_dataclasses_check_their_fields_and_across_them():
    from gevsim._validate import FieldError
    from gevsim.emulation.emulators import GradientConfig, SurroundConfig

    assert GradientConfig(thresholds_ln=[1, 2], hysteresis_ln=0).thresholds_ln == (1.0, 2.0)
    with pytest.raises(FieldError, match="hysteresis_ln = 0.1 must be below the smallest threshold 0.05") as err:
        GradientConfig(thresholds_ln=(0.2, 0.05), hysteresis_ln=0.1)
    assert err.value.field == "hysteresis_ln"
    with pytest.raises(FieldError, match="thresholds_ln must be a non-empty list of positive numbers"):
        GradientConfig(thresholds_ln=[])
    with pytest.raises(FieldError, match="surround_length_px must be finite and in \\(0, 10000\\]"):
        SurroundConfig(surround_length_px=0.0)


def test_report_roles_come_from_the_registry():
    from gevsim.emulation.emulators import HEADLINE

    assert HEADLINE == ("dvs", "gradient")  # the rejection ratio: DVS over gradient flicker-induced rates
    assert {n: e.kind for n, e in EMULATORS.items()} == {"dvs": "brightness", "gradient": "gradient",
                                                         "gradient_rc": "gradient", "csdvs": "center_surround"}
    for method in METHODS.values():  # reports group reconstructions by their stream's kind
        assert EMULATORS[method.emulator].kind in ("brightness", "gradient")
