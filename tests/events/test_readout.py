"""Readout: at most max_rate_eps events per second leave the sensor through an AER arbiter that holds one
request per pixel (issues 23 and 34); delays, drops, crossings a waiting pixel could not send and pixels
still waiting at the end are counted. The arbitration laws themselves: tests/events/test_arbiter.py."""

from __future__ import annotations

import numpy as np
import pytest

from gevsim.events.readout import Readout, ReadoutParams
from gevsim.events.types import BRIGHTNESS_DTYPE


def requests(t_us) -> np.ndarray:
    ev = np.zeros(len(t_us), BRIGHTNESS_DTYPE)
    ev["t"] = t_us
    ev["x"] = np.arange(len(t_us)) % 100
    ev["y"] = (np.arange(len(t_us)) // 100) % 100
    return ev


def test_a_burst_of_one_row_leaves_one_event_per_service_time_in_column_order():
    r = Readout(ReadoutParams(max_rate_eps=1e6), shape=(100, 100))  # one event per microsecond
    out = r.process(requests(np.zeros(10, np.int64)))
    np.testing.assert_array_equal(out["t"], np.arange(10))
    np.testing.assert_array_equal(out["x"], np.arange(10))  # the column burst reads the row left to right
    s = r.summary()
    assert (s["requested"], s["delivered"], s["delayed"], s["dropped"], s["unsent"]) == (10, 10, 9, 0, 0)
    assert s["mean_delay_us"] == pytest.approx(5.0) and s["max_delay_us"] == pytest.approx(9.0)


def test_sustained_overload_delivers_the_bus_rate_and_counts_the_rest():
    rate, n = 1e5, 20_000  # 2e5 requests per second for 0.1 s into a 1e5 eps bus
    t = np.sort(np.random.default_rng(0).integers(0, 100_000, n))
    r = Readout(ReadoutParams(max_rate_eps=rate), shape=(100, 100))
    out = np.concatenate([r.process(requests(t[a:b]), end_us=100_000, until_us=u)
                          for a, b, u in ((0, 7000, int(t[7000])), (7000, n, None))])
    s = r.summary()
    assert s["requested"] == s["delivered"] + s["dropped"] + s["pending_at_end"] + s["unsent"] == n
    assert s["delivered"] == pytest.approx(rate * 0.1, abs=2) and len(out) == s["delivered"]
    assert s["pending_at_end"] <= 100 * 100  # one request per pixel at the most
    assert np.all(np.diff(out["t"]) >= 0)
    for w in (10, 1000):  # no window of w us holds more than rate * w + 1 events
        counts = np.searchsorted(out["t"], out["t"] + w, side="left") - np.arange(len(out))
        assert counts.max() <= rate * w * 1e-6 + 1


def test_events_waiting_too_long_are_dropped():
    r = Readout(ReadoutParams(max_rate_eps=1e6, max_delay_s=4.5e-6), shape=(100, 100))
    out = r.process(requests(np.zeros(10, np.int64)))
    np.testing.assert_array_equal(out["t"], np.arange(5))  # waits of 0..4 us; the rest would wait >= 5 us
    assert r.summary()["dropped"] == 5


def test_chunks_and_no_limit():
    t = np.sort(np.random.default_rng(1).integers(0, 1000, 3000))
    ev = requests(t)
    one = Readout(ReadoutParams(max_rate_eps=2e6), shape=(100, 100)).process(ev)
    r = Readout(ReadoutParams(max_rate_eps=2e6), shape=(100, 100))
    parts = np.concatenate([r.process(ev[a:b], until_us=None if b == 3000 else int(t[b]))
                            for a, b in ((0, 1), (1, 1700), (1700, 3000))])
    np.testing.assert_array_equal(one, parts)
    assert Readout(ReadoutParams()).process(ev) is ev  # no limit: untouched
    with pytest.raises(ValueError, match="max_rate_eps"):
        ReadoutParams(max_rate_eps=0.0)
    with pytest.raises(ValueError, match="shape"):
        Readout(ReadoutParams(max_rate_eps=1e6))
    with pytest.raises(ValueError, match="arbitration"):
        ReadoutParams(arbitration="lottery")


def test_the_driver_reads_every_stream_through_the_sensors_bus(tmp_path):
    """A flickering card read through a 200 keps bus: the file holds what was delivered, the rest
    is counted in readout_json (conservation), and no 1 ms holds more than the bus carries."""
    import json
    import types
    from pathlib import Path

    from gevsim.emulation import EmulationConfig, run
    from gevsim.emulation.driver import Setup
    from gevsim.illumination import from_spec
    from gevsim.io import EventReader
    from gevsim.pixel import load_preset
    from gevsim.pixel.presets import with_overrides
    from gevsim.render import load

    data = Path(__file__).parents[1] / "data"
    manifest = load(data / "card.toml")
    h, w = manifest.render.height, manifest.render.width
    lamp = from_spec({"type": "pwm", "frequency_hz": 500.0, "duty": 0.3, "low_level": 0.3})
    preset = with_overrides(load_preset("davis346"), {"max_rate_eps": 2e5})  # as [sensor] overrides do
    setup = Setup(manifest=manifest, preset=preset, basis_times_s=np.array([0.0]),
                  current_basis=np.full((1, 1, h, w), 2e-10), waveforms=(lamp,), duration_s=0.01,
                  variant=types.SimpleNamespace(variant="none"), current_noise=None, render_quality={})
    config = EmulationConfig(scene=str(data / "card.toml"), seed=3, duration_s=0.01, emulators=("dvs",),
                             frame_rate_hz=0.0)
    run(config, tmp_path / "r.h5", setup=setup)
    with EventReader(tmp_path / "r.h5") as r:
        ev = r.read("events")
        s = json.loads(r.attrs["readout_json"])["events"]
    assert s["delayed"] > 0 and s["delivered"] == len(ev)
    assert s["requested"] == s["delivered"] + s["dropped"] + s["pending_at_end"] + s["unsent"]
    assert s["pending_at_end"] <= h * w
    per_ms = np.bincount(ev["t"] // 1000)
    assert per_ms.max() <= 2e5 * 1e-3 + 1


def test_an_emulation_gets_the_chips_bus_per_pixel():
    """96x72 pixels viewing a davis346's field: 12 Meps x 6912 / 89960 = 0.922 Meps (133 ev/px/s, as the chip)."""
    from gevsim.events.readout import chip_share
    from gevsim.pixel import load_preset

    p = load_preset("davis346")
    share = chip_share(p.readout, emulated_px=96 * 72, chip_px=p.width * p.height)
    assert share.max_rate_eps == pytest.approx(12e6 * 6912 / 89960)
    assert share.max_rate_eps / 6912 == pytest.approx(p.readout.max_rate_eps / (346 * 260))
    assert share.latency_s == p.readout.latency_s
    with pytest.raises(ValueError):
        chip_share(p.readout, emulated_px=0, chip_px=10)


def test_readout_stages_are_a_registry_in_order():
    """Each mechanism between the comparators and the bus is one READOUT_STAGES entry with its source; a
    readout runs the enabled ones in the registry's order."""
    from gevsim.events.readout import READOUT_STAGES, Readout
    from gevsim.pixel.params import ReadoutParams

    assert all(stage.source for stage in READOUT_STAGES.values())
    everything = ReadoutParams(latency_s=1e-6, anti_flicker=True, rate_controller_eps=1e6)
    assert list(Readout(everything, shape=(4, 4)).stages) == list(READOUT_STAGES)
    assert list(Readout(ReadoutParams(rate_controller_eps=1e6)).stages) == ["rate_controller"]
    assert not Readout(ReadoutParams()).stages
