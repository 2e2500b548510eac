"""The shared input checks: values pass through converted, and errors name the parameter and the value."""

import numpy as np
import pytest

from gevsim._validate import FieldError, FieldTypeError, increasing, integer, real, real_array, real_list, size
from gevsim.config import FieldError as ConfigFieldError


def test_real_converts_and_checks_bounds():
    assert real(2, "gain") == 2.0 and isinstance(real(np.float32(0.5), "gain"), float)
    assert real(np.array(3.0), "gain") == 3.0
    assert real(float("inf"), "cutoff_hz", low=0, low_open=True, allow_inf=True) == float("inf")
    assert real(1.0, "duty", low=0, high=1, low_open=True) == 1.0
    with pytest.raises(FieldError, match=r"^gain must be finite and > 0, got 0$") as info:
        real(0, "gain", low=0, low_open=True)
    assert info.value.field == "gain"
    with pytest.raises(ValueError, match=r"duty must be finite and in \(0, 1\], got 1.5"):
        real(1.5, "duty", low=0, high=1, low_open=True)
    with pytest.raises(ValueError, match=r"x must be finite and in \[0, 1\), got 1.0"):
        real(1.0, "x", low=0, high=1, high_open=True)
    with pytest.raises(ValueError, match="must be finite, got nan"):
        real(float("nan"), "v0_v")
    with pytest.raises(ValueError, match=r"must be a number and > 0, got nan"):
        real(float("nan"), "cutoff_hz", low=0, low_open=True, allow_inf=True)
    with pytest.raises(ValueError, match="got inf"):
        real(float("inf"), "gain")


@pytest.mark.parametrize("value", ["fast", True, None, [1.0]])
def test_a_value_of_the_wrong_type_is_a_type_error_and_a_field_error(value):
    with pytest.raises(FieldTypeError, match=f"gain must be a real number, got {value!r}"[:30]) as info:
        real(value, "gain")
    assert isinstance(info.value, TypeError) and isinstance(info.value, ValueError)
    assert isinstance(info.value, ConfigFieldError)  # what FromTable turns into a ConfigError


def test_integer_and_size():
    assert integer(np.int64(3), "n", low=1) == 3 and type(integer(np.int64(3), "n")) is int
    with pytest.raises(ValueError, match="harmonics must be a positive integer, got 0"):
        integer(0, "harmonics", low=1)
    with pytest.raises(ValueError, match=r"bit_depth must be an integer in 8\.\.16, got 40"):
        integer(40, "bit_depth", low=8, high=16)
    with pytest.raises(ValueError, match="n_events must be an integer >= 0, got -1"):
        integer(-1, "n_events", low=0)
    with pytest.raises(TypeError, match="samples must be an integer >= 2, got 2.0"):
        integer(2.0, "samples", low=2)
    with pytest.raises(TypeError):
        integer(True, "n")
    assert size(np.int32(4), 3) == (4, 3)
    with pytest.raises(ValueError, match="height must be a positive integer, got 0"):
        size(4, 0)


def test_real_list():
    assert real_list([1, 2.5], "thresholds", positive=True) == (1.0, 2.5)
    assert real_list(np.array([0.1, 0.2]), "thresholds") == (0.1, 0.2)
    for bad in ([], [0.1, -1], [0.1, float("nan")], "0.1", [[0.1]], 0.1):
        with pytest.raises(ValueError, match="thresholds must be a non-empty list of positive numbers, got"):
            real_list(bad, "thresholds", positive=True)


def test_real_array_counts_and_shows_the_first_bad_value():
    a = real_array([1, 2], "x")
    assert a.dtype == np.float64
    f32 = np.ones(3, np.float32)
    assert real_array(f32, "x").dtype == np.float32 and real_array(f32, "x", dtype=np.float64).dtype == np.float64
    bad = np.zeros((2, 3))
    bad[1, 2] = bad[0, 1] = np.nan
    first = r"first img\[0, 1\] = nan$"
    with pytest.raises(ValueError, match=r"^img has 2 non-finite value\(s\) \(NaN or inf\) out of 6, " + first):
        real_array(bad, "img")
    with pytest.raises(ValueError, match=r"radiance has 1 negative .* \(min -2.0\), first radiance\[1\] = -2.0"):
        real_array([1.0, -2.0, 0.0], "radiance", nonnegative=True)
    with pytest.raises(ValueError, match=r"rate has 1 negative value\(s\) out of 1 \(min -1.0\), got -1.0"):
        real_array(-1.0, "rate", nonnegative=True)
    with pytest.raises(TypeError, match="must be a real numeric array, got dtype <U1"):
        real_array(["a"], "x")


def test_increasing_names_the_first_step_back():
    t = np.array([0, 5, 9])
    assert increasing(t, "t_us", unit="us") is not None and increasing(t, "t_us").dtype == t.dtype
    with pytest.raises(ValueError, match=r"^t_s must increase strictly: frame 2 at 0.1 s follows 0.2 s$"):
        increasing([0.0, 0.2, 0.1], "t_s", what="frame")
    with pytest.raises(ValueError, match=r"t_s must be finite: 1 of 2 values are NaN or infinite"):
        increasing([0.0, np.inf], "t_s")
    with pytest.raises(ValueError, match=r"non-empty 1-D array of times in us, got shape \(0,\)"):
        increasing([], "t", unit="us")
    with pytest.raises(TypeError, match="numeric times"):
        increasing(["a"], "t")
