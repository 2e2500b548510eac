"""Waveforms: mean 1, exact cumulative/average, validation of config input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gevsim.errors import ConfigError
from gevsim.illumination import (
    DC,
    PWM,
    WAVEFORMS,
    Fluorescent,
    Incandescent,
    Sinusoid,
    SodiumHID,
    Table,
    from_spec,
)
from gevsim.illumination.mains import first_order_response

WAVEFORM_CASES = {
    "dc": DC(),
    "sin": Sinusoid(100.0),
    "sin-phase": Sinusoid(37.0, modulation=0.4, phase_rad=1.3),
    "pwm-ideal": PWM(200.0, 0.3),
    "pwm-full": PWM(200.0, 1.0),
    "pwm-edges": PWM(1000.0, 0.25, rise_s=5e-5, fall_s=1e-4, phase_s=3e-4),
    "pwm-dimmer": PWM(125.0, 0.6, rise_s=1e-3, fall_s=2e-4, phase_s=-1e-3, low_level=0.2),
    "pwm-triangle": PWM(100.0, 0.5, rise_s=5e-3, fall_s=5e-3),
    "fluorescent": Fluorescent(),
    "fluorescent-60": Fluorescent(60.0, persistence_s=2e-3, phase_rad=2.0),
    "fluorescent-m": Fluorescent(modulation=0.7),
    "incandescent": Incandescent(),
    "sodium": SodiumHID(),
    "sodium-60": SodiumHID(60.0, reignition_fraction=0.05, persistence_s=1e-4, phase_rad=0.5),
    "table": Table([0.0, 0.01, 0.03, 0.035], [1.0, 3.0, 0.0, 2.0]),
    "table-offset": Table([0.2, 0.21, 0.25], [5.0, 1.0, 2.0]),
    "table-periodic": Table([0.1, 0.11, 0.13], [1.0, 3.0, 0.5], periodic=True),
}
CASES = list(WAVEFORM_CASES.values())
IDS = list(WAVEFORM_CASES)


def _span(w):
    a, b = w.reference_span()
    return a, b


def _gauss_integral(w, t, cell=2.5e-6, order=8):
    """Integral of w over [0, t] by Gauss-Legendre on cells; every knot of the cases is a cell edge."""
    n = round(abs(t) / cell)
    x, wt = np.polynomial.legendre.leggauss(order)
    edges = np.sign(t) * cell * np.arange(n)[:, None]
    nodes = edges + np.sign(t) * 0.5 * cell * (x + 1)
    return float(np.sign(t) * 0.5 * cell * np.sum(w(nodes) * wt))


@pytest.mark.parametrize("w", CASES, ids=IDS)
def test_mean_is_one(w):
    assert abs(w.mean_value - 1.0) < 1e-9
    a, b = _span(w)
    t = np.linspace(a, b, 200_001)
    assert abs(np.trapezoid(w(t), t) / (b - a) - 1.0) < 2e-3  # independent check


@pytest.mark.parametrize("w", CASES, ids=IDS)
def test_values_non_negative_same_shape(w):
    t = np.linspace(-0.05, 0.2, 1200).reshape(3, 400)
    v = w(t)
    assert v.shape == t.shape and v.dtype == np.float64
    assert np.all(v >= 0)
    assert np.ndim(w(0.01)) == 0


@pytest.mark.parametrize("w", CASES, ids=IDS)
def test_cumulative_matches_quadrature(w):
    c0 = float(w.cumulative(0.0))
    assert c0 == pytest.approx(0.0, abs=1e-15)
    for t in (-0.013, 0.0021, 0.0173, 0.0481):
        assert float(w.cumulative(t)) == pytest.approx(_gauss_integral(w, t), abs=1e-10)
    t = np.array([[0.0021, 0.0173], [-0.013, 0.0481]])
    assert w.cumulative(t).shape == (2, 2)


@pytest.mark.parametrize("w", [c for c in CASES if c.period_s is not None],
                         ids=[i for i, c in zip(IDS, CASES) if c.period_s is not None])
def test_average_over_whole_periods_is_one(w):
    p = w.period_s
    starts = np.array([-1.234, 0.0, 0.00037, 3.5, 1000.1])
    for n in (1, 3, 17):
        np.testing.assert_allclose(w.average(starts, starts + n * p), 1.0, atol=1e-9)


@pytest.mark.parametrize("w", CASES, ids=IDS)
def test_average_empty_interval_is_value(w):
    t = np.array([0.001, 0.0123, 0.5])
    np.testing.assert_allclose(w.average(t, t), w(t), rtol=0, atol=0)


@pytest.mark.parametrize("w", CASES, ids=IDS)
@settings(max_examples=40, deadline=None)
@given(a=st.floats(-1.0, 1.0), width=st.floats(1e-6, 0.1))
def test_average_between_min_and_max(w, a, width):
    lo, hi = w.value_range()
    avg = float(w.average(a, a + width))
    assert lo - 1e-6 <= avg <= hi + 1e-6


def test_average_of_short_step_at_large_time_is_accurate():
    w = Sinusoid(50.0)
    t0 = 1.0e4 + 0.005  # phase pi/2: peak
    assert float(w.average(t0 - 1e-7, t0 + 1e-7)) == pytest.approx(2.0, abs=1e-5)


def test_pwm_shape():
    w = PWM(100.0, 0.25)  # peak 1 / duty = 4, off 0
    t = np.array([0.0005, 0.002, 0.0026, 0.009, 0.0105])
    np.testing.assert_allclose(w(t), [4.0, 4.0, 0.0, 0.0, 4.0])
    dim = PWM(100.0, 0.5, low_level=0.5)  # levels 0.5 and 1 scaled by 1/0.75
    np.testing.assert_allclose(dim(np.array([0.001, 0.006])), [4 / 3, 2 / 3])


def test_pwm_duty_is_time_above_half_level():
    w = PWM(50.0, 0.4, rise_s=2e-3, fall_s=4e-3, low_level=0.1)
    lo, hi = w.value_range()
    t = (np.arange(200_000) + 0.5) * (w.period_s / 200_000)
    assert np.mean(w(t) >= 0.5 * (lo + hi)) == pytest.approx(0.4, abs=1e-4)


def test_fluorescent_analytic_shape():
    f, tau = 50.0, 3e-3
    a, phi = first_order_response(f, tau)
    t = np.linspace(0, 0.05, 101)
    np.testing.assert_allclose(Fluorescent(f, persistence_s=tau)(t), 1 - a * np.cos(4 * np.pi * f * t - phi),
                               atol=1e-12)
    assert a == pytest.approx(1 / math.sqrt(1 + (4 * math.pi * f * tau) ** 2))


def test_sodium_is_dark_at_current_zero():
    w = SodiumHID(50.0, persistence_s=0.0)
    assert float(w(0.0)) == 0.0 and float(w(0.01)) == 0.0
    assert float(w(0.005)) == pytest.approx(w.value_range()[1])


@pytest.mark.parametrize("w", CASES, ids=IDS)
def test_constant_is_dc_with_same_mean(w):
    c = w.constant()
    assert c == DC() and c.mean_value == pytest.approx(w.mean_value, abs=1e-9)


def test_table_holds_ends_and_repeats():
    w = Table([1.0, 2.0], [1.0, 3.0])  # scaled by 1/2
    np.testing.assert_allclose(w(np.array([0.0, 1.5, 5.0])), [0.5, 1.0, 1.5])
    assert float(w.cumulative(3.0)) == pytest.approx(0.5 + 1.0 + 1.5)
    p = Table([0.0, 1.0, 2.0], [0.0, 2.0, 0.0], periodic=True)
    assert p.period_s == 2.0
    np.testing.assert_allclose(p(np.array([1.0, 3.0, -1.0, 2.5])), [2.0, 2.0, 2.0, 1.0])


def test_from_spec_builds_each_type():
    specs = {
        "dc": {}, "sinusoid": {"frequency_hz": 100}, "pwm": {"frequency_hz": 200, "duty": 0.3},
        "fluorescent": {"mains_hz": 60}, "incandescent": {}, "sodium_hid": {"reignition_fraction": 0.1},
        "table": {"times_s": [0, 1], "values": [1, 2], "periodic": True},
    }
    assert set(specs) == set(WAVEFORMS)
    for name, fields in specs.items():
        w = from_spec({"type": name, **fields})
        assert isinstance(w, WAVEFORMS[name]) and w.mean_value == pytest.approx(1.0, abs=1e-9)
    assert from_spec({"type": "pwm", "frequency_hz": 200, "duty": 0.3}) == PWM(200.0, 0.3)


@pytest.mark.parametrize(
    ("spec", "key", "fragment"),
    [
        ({"type": "pmw", "frequency_hz": 1, "duty": 0.5}, "lamp.type", "did you mean 'pwm'"),
        ({"frequency_hz": 1}, "lamp", "missing 'type'"),
        ({"type": "pwm", "frequency_hz": 1, "dutty": 0.5}, "lamp.dutty", "did you mean 'duty'"),
        ({"type": "pwm", "frequency_hz": 100}, "lamp.duty", "missing required"),
        ({"type": "pwm", "frequency_hz": 100, "duty": 1.5}, "lamp.duty", "1.5"),
        ({"type": "pwm", "frequency_hz": 100, "duty": 0.0}, "lamp.duty", "0.0"),
        ({"type": "pwm", "frequency_hz": -5, "duty": 0.5}, "lamp.frequency_hz", "-5"),
        ({"type": "pwm", "frequency_hz": 100, "duty": 0.5, "rise_s": 0.006, "fall_s": 0.006},
         "lamp.rise_s", "do not fit"),
        ({"type": "sinusoid", "frequency_hz": float("nan")}, "lamp.frequency_hz", "nan"),
        ({"type": "sinusoid", "frequency_hz": "fast"}, "lamp.frequency_hz", "'fast'"),
        ({"type": "sinusoid", "frequency_hz": 10, "modulation": 1.2}, "lamp.modulation", "1.2"),
        ({"type": "fluorescent", "persistence_s": 1e-3, "modulation": 0.3}, "lamp.modulation", "not both"),
        ({"type": "table", "times_s": [0, 1, 2], "values": [0, 0, 0]}, "lamp.values", "zero mean"),
        ({"type": "table", "times_s": [0, 1, 1], "values": [1, 2, 3]}, "lamp.times_s", "increase strictly: entry 2"),
        ({"type": "table", "times_s": [0, 1], "values": [1, float("nan")]}, "lamp.values", "nan"),
        ({"type": "table", "times_s": [0, 1], "values": [1, -1]}, "lamp.values", "-1"),
        ({"type": "table", "times_s": [0, 1], "values": [1, 2, 3]}, "lamp.values", "3 samples"),
    ],
)
def test_from_spec_rejects_bad_input(spec, key, fragment):
    with pytest.raises(ConfigError) as info:
        from_spec(spec, source="scene.toml", key="lamp")
    assert info.value.key == key and info.value.source == "scene.toml"
    assert fragment in str(info.value)
    assert str(info.value).startswith(f"scene.toml: {key}: ")


def test_direct_construction_raises_value_error_naming_value():
    with pytest.raises(ValueError, match=r"duty must be finite and in \(0, 1\], got 1.5"):
        PWM(100.0, 1.5)
    with pytest.raises(ValueError, match=r"reignition_fraction must be finite and in \[0, 1\), got 1.0"):
        SodiumHID(reignition_fraction=1.0)


def test_waveforms_are_hashable_values():
    assert hash(Table([0, 1], [1, 2])) == hash(Table((0.0, 1.0), (1.0, 2.0)))
    assert Fluorescent() == Fluorescent(50.0) and Fluorescent() != Fluorescent(60.0)


def test_lamp_types_know_how_studies_sweep_and_datasets_draw_them():
    from gevsim.experiments.dataset import Randomize
    from gevsim.illumination.spec import RANDOM_WAVEFORMS, SWEPT_WAVEFORMS, random_spec, swept_spec

    assert SWEPT_WAVEFORMS == RANDOM_WAVEFORMS == tuple(n for n in WAVEFORMS if n != "table")
    for name in SWEPT_WAVEFORMS:  # each spec is a valid table whose light flickers at the swept frequency
        wave = from_spec(swept_spec(name, 240.0, {"duty": 0.3, "modulation": 0.5}))
        assert wave.period_s is None if name == "dc" else wave.period_s == pytest.approx(1 / 240.0)
    assert swept_spec("fluorescent", 100.0, {"modulation": 0.5}) == {"type": "fluorescent", "mains_hz": 50.0,
                                                                       "modulation": 0.5}
    ranges = Randomize(waveforms=RANDOM_WAVEFORMS, mains_hz=(50.0, 60.0))
    for name in RANDOM_WAVEFORMS:
        a, b = (random_spec(name, np.random.default_rng(3), ranges, phase_rad=1.0) for _ in range(2))
        assert a == b and isinstance(from_spec(a), WAVEFORMS[name])
    rng = np.random.default_rng(3)
    drawn = random_spec("pwm", rng, ranges, phase_rad=1.0)  # log-uniform frequency, then the duty: 2 draws
    check = np.random.default_rng(3)
    check.uniform(), check.uniform()
    assert rng.uniform() == check.uniform() and 100.0 <= drawn["frequency_hz"] <= 2000.0
    with pytest.raises(NotImplementedError):
        Table.swept(100.0, {})
