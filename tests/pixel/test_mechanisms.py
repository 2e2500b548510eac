"""The registry of noise mechanisms (issue 33): every preset key of a noise mechanism has one owner,
the ideal pixel has every mechanism off, and the kernel's coefficients are the sums of the entries'."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.constants import elementary_charge

from gevsim.pixel import Photoreceptor, PhotoreceptorParams, load_preset, preset_names
from gevsim.pixel.mechanisms import NOISE_MECHANISMS, Mechanism, _base, ideal_values, kernel_noise, mechanisms_on
from gevsim.pixel.mechanisms.dc_offset import DcOffset
from gevsim.pixel.params import EventParams, NoiseParams

TABLES = {"noise": NoiseParams, "events": EventParams}
#: EventParams' own keys: the comparators themselves, not a noise.
COMPARATOR_KEYS = {"threshold_on_ln", "threshold_off_ln", "refractory_s"}


def owners(key: str) -> list[str]:
    return [name for name, m in NOISE_MECHANISMS.items() if key in m.keys]


@pytest.mark.parametrize("table", sorted(TABLES))
def test_every_key_has_one_owner_and_every_entry_is_wired(table):
    cls = TABLES[table]
    for f in dataclasses.fields(cls):
        expected = 0 if table == "events" and f.name in COMPARATOR_KEYS else 1
        assert len(owners(f.name)) == expected, f"{table}.{f.name}: owners {owners(f.name)}"
    for name, m in NOISE_MECHANISMS.items():
        if m.table == table:
            assert issubclass(cls, m.params), f"{name}: {m.params.__name__} is not a base of {cls.__name__}"
            assert m.source and m.stream and m.off, name


@pytest.mark.parametrize("preset", sorted(preset_names()))
def test_the_ideal_pixel_has_every_mechanism_off_but_the_keys_it_says_why_it_keeps(preset):
    sensor = load_preset(preset)
    ideal = sensor.ideal()
    tables = {"noise": (sensor.noise, ideal.noise), "events": (sensor.events, ideal.events)}
    for name, m in NOISE_MECHANISMS.items():
        real, ideal_table = tables[m.table]
        for key, off in m.off.items():
            if key in m.ideal_keeps:
                assert len(m.ideal_keeps[key]) > 20, f"{name}.{key}: say why the ideal pixel keeps it"
                assert getattr(ideal_table, key) == getattr(real, key)
            else:
                assert getattr(ideal_table, key) == off, f"{name}.{key} is on in the ideal pixel"
    assert ideal.noise.dark_current_a == sensor.noise.dark_current_a  # the log floor is not a noise
    assert ideal.events.threshold_on_ln == sensor.events.threshold_on_ln
    plan = kernel_noise(ideal.noise, ideal.photoreceptor.volts_per_ln)
    assert not plan.on_photoreceptor_pole and plan.poles()[0].size == 0


def test_davis346_mechanisms_and_what_its_ideal_keeps():
    sensor = load_preset("davis346")
    on = set(mechanisms_on(sensor.noise, sensor.events))
    assert {"shot", "read", "leak", "comparator_offset", "dc_offset", "dark_current", "prnu"} <= on
    assert "flicker" not in on
    ideal = sensor.ideal()
    assert set(mechanisms_on(ideal.noise, ideal.events)) == {"comparator_offset"}  # stated, not silent
    # The light leak is off too since the DVS levels start from their stationary law whatever the leak (issue 34).
    assert ideal.events.leak_rate_hz == 0.0 and ideal.events.leak_light_hz_per_a == 0.0


def test_kernel_coefficients_are_the_sums_of_the_entries():
    vpl = PhotoreceptorParams().volts_per_ln
    one = kernel_noise(NoiseParams(shot_noise=True), vpl)
    two = kernel_noise(NoiseParams(shot_noise=True, feedback_shot_noise=True), vpl)
    assert one.shot_q == math.pi * elementary_charge
    assert two.shot_q == 2 * one.shot_q  # the feedback transistor: a second equal source
    assert kernel_noise(NoiseParams(shot_noise=False, feedback_shot_noise=True), vpl).shot_q == 0.0
    plan = kernel_noise(NoiseParams(read_noise_v=1e-3, read_noise_bandwidth_hz=2e3, flicker_noise_v=2e-3,
                                    amplifier_noise_ln2_hz=0.05), vpl)
    hz, var = plan.poles()
    assert plan.n_cascaded == 1 and hz[0] == 2e3 and var[0] == pytest.approx((1e-3 / vpl) ** 2, rel=1e-15)
    assert hz[1] == 1.0 and hz[-1] == 1000.0  # the 1/f poles' corners follow the read noise
    assert var[1:].sum() == pytest.approx((2e-3 / vpl) ** 2, rel=1e-12)  # 1/f: total variance
    assert plan.amp_ln2_hz == 0.05


def test_streams_are_distinct():
    names = [n for n in dir(_base) if n.startswith("STREAM_")]
    values = [getattr(_base, n) for n in names]
    assert len(set(values)) == len(values) == 4


def test_an_entry_cannot_switch_off_keys_it_does_not_own():
    with pytest.raises(ValueError, match="does not own"):
        Mechanism(DcOffset, "noise", {"prnu": 0.0}, "test", "none")


def test_a_new_output_pattern_is_one_entry(monkeypatch):
    """A mechanism with a ``pattern`` hook reaches the photoreceptor's output with no other change."""
    def plus_one(noise, n, volts_per_ln, rng):
        return np.full(n, 1.0, np.float32)

    def run(noise):
        pr = Photoreceptor((2, 3), params=PhotoreceptorParams(), noise=noise, rng=np.random.default_rng(0))
        return pr.process(np.full((2, 2, 3), 1e-12), np.array([1e-4, 2e-4]))

    quiet = NoiseParams(shot_noise=False)
    before = run(quiet)
    registry = dict(NOISE_MECHANISMS)
    registry["test_pattern"] = Mechanism(DcOffset, "noise", {"dc_offset_v": 0.0}, "test", "none", pattern=plus_one)
    monkeypatch.setattr("gevsim.pixel.mechanisms.NOISE_MECHANISMS", registry)
    monkeypatch.setattr("gevsim.pixel.photoreceptor.NOISE_MECHANISMS", registry)
    assert np.array_equal(run(quiet), before)  # off: not drawn
    on = NoiseParams(shot_noise=False, dc_offset_v=1e-9)  # both dc_offset and the test entry on
    assert np.allclose(run(on) - before, 1.0, atol=1e-6)
    assert ideal_values("noise")["dc_offset_v"] == 0.0
