"""Sensor presets: every shipped preset loads; paper values; clear errors."""

import pytest

from gevsim.errors import ConfigError
from gevsim.pixel import load_preset, preset_names
from gevsim.pixel.presets import lux_to_photocurrent_a


def test_all_presets_load():
    assert {"ideal", "dvs128", "davis346", "imx636"} <= set(preset_names())
    for name in preset_names():
        p = load_preset(name)
        assert p.width > 0 and p.photoreceptor.cutoff_ref_photocurrent_a > 0


def test_paper_values():
    dvs = load_preset("dvs128")
    assert dvs.events.threshold_mismatch_ln == 0.021  # Lichtsteiner et al. 2008: 2.1 %
    assert (dvs.width, dvs.height, dvs.pixel_pitch_m) == (128, 128, 40e-6)
    assert load_preset("imx636").pixel_pitch_m == 4.86e-6  # Finateu et al. 2020
    assert load_preset("davis346").aps.bit_depth == 10


def test_bandwidth_reference_follows_pixel_area():
    # cutoff at 1 klux converted with the pixel area: photocurrent scales with pitch^2 * fill factor.
    a = lux_to_photocurrent_a(1000.0, pixel_pitch_m=40e-6, fill_factor=0.081)
    b = lux_to_photocurrent_a(1000.0, pixel_pitch_m=20e-6, fill_factor=0.081)
    assert a == pytest.approx(4 * b)
    ref = lux_to_photocurrent_a(57.4, pixel_pitch_m=40e-6, fill_factor=0.094)  # L08's 1 klux scene = 57.4 chip lux
    assert load_preset("dvs128").photoreceptor.cutoff_ref_photocurrent_a == pytest.approx(ref)


def test_ideal_preset_is_noise_free():
    p = load_preset("ideal")
    assert not p.noise.shot_noise and p.noise.read_noise_v == 0 and p.events.threshold_mismatch_ln == 0
    q = load_preset("dvs128").ideal()
    assert not q.noise.shot_noise and q.events.threshold_mismatch_ln == 0 and q.pixel_pitch_m == 40e-6
    assert load_preset("dvs128").events.reset_noise_ln > 0
    assert q.events.reset_noise_ln == 0 and q.events.leak_rate_hz == 0
    assert q.photoreceptor == load_preset("dvs128").photoreceptor  # bandwidth is not noise: kept


def test_unknown_preset_suggests():
    with pytest.raises(ConfigError, match="did you mean 'dvs128'"):
        load_preset("dvs129")


@pytest.mark.parametrize(
    "text, key",
    [
        ("[noise]\nshot_noize = true\n", "noise.shot_noize"),
        ("[noise]\nread_noise_v = -1.0\n", "noise.read_noise_v"),
        ("[events]\nthreshold_on_ln = 0\n", "events.threshold_on_ln"),
        ("[photoreceptor]\ncutoff_hz = -5.0\n", "photoreceptor.cutoff_hz"),
        ("[sensor]\nfill_factor = 1.5\n", "sensor.fill_factor"),
        ("[aps]\nbit_depth = 40\n", "aps.bit_depth"),
    ],
)
def test_bad_preset_names_file_and_key(tmp_path, text, key):
    base = (load_preset("dvs128").source)
    from pathlib import Path

    lines = Path(base).read_text()
    table, entry = text.split("\n")[0], text.split("\n")[1]
    name = entry.split("=")[0].strip()
    if table in lines:
        import re

        body = re.sub(rf"^{name}\s*=.*$", "", lines, flags=re.M)
        body = body.replace(table + "\n", f"{table}\n{entry}\n", 1)
    else:
        body = lines + "\n" + text
    bad = tmp_path / "bad.toml"
    bad.write_text(body)
    with pytest.raises(ConfigError) as err:
        load_preset(bad)
    assert str(bad) in str(err.value) and key in str(err.value)


def test_overrides_reach_the_right_parameter_group():
    from gevsim.pixel.presets import with_overrides

    p = with_overrides(load_preset("davis346"), {"threshold_mismatch_ln": 0.0, "cutoff_hz": 500.0,
                                                 "dark_current_a": 1e-14, "pixel_pitch_m": 9e-6})
    assert p.events.threshold_mismatch_ln == 0.0 and p.photoreceptor.cutoff_hz == 500.0
    assert p.noise.dark_current_a == 1e-14 and p.pixel_pitch_m == 9e-6
    with pytest.raises(ConfigError, match="did you mean 'cutoff_hz'"):
        with_overrides(p, {"cuttoff_hz": 1.0})
    with pytest.raises(ConfigError, match="cutoff_hz"):
        with_overrides(p, {"cutoff_hz": -1.0})
