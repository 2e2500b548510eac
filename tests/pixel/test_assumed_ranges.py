"""Every number a shipped preset marks ``# assumed`` has a plausible range with a reason (issue 35, item 3),
and the ranges are usable: each end is a valid override of that field and nothing else.
"""

from __future__ import annotations

import dataclasses
import re

import pytest

from gevsim.errors import ConfigError
from gevsim.pixel.assumed import ASSUMED_TABLES, Assumed
from gevsim.pixel.presets import load_preset, parameter_value, preset_names, with_overrides

SHIPPED = ("davis346", "dvs128", "imx636")
FIELD = re.compile(r"^(\w+)\s*=\s*[^#]*?(#.*)?$")


def marked_assumed(text: str) -> set[str]:
    """``table.field`` of every line ``field = value  # ... assumed ...`` (or its indented comment lines) inside one
    of the tables an assumption may range over."""
    out: set[str] = set()
    table, field = None, None
    for line in text.splitlines():
        if header := re.match(r"^\[([\w.]+)\]", line):
            table, field = header.group(1), None
            continue
        if table not in ASSUMED_TABLES:
            continue
        if m := FIELD.match(line):
            field = m.group(1)
            comment = m.group(2) or ""
        elif field and re.match(r"^\s+#", line):
            comment = line
        else:
            field = None if not line.strip() or line.startswith("#") else field
            continue
        if "assumed" in comment.lower():
            out.add(f"{table}.{field}")
    return out


@pytest.mark.parametrize("name", SHIPPED)
def test_every_assumed_number_has_a_range(name):
    preset = load_preset(name)
    marked = marked_assumed(preset_names()[name].read_text())
    assert marked, "the parser found no assumed numbers: the regex is wrong"
    missing = sorted(marked - set(preset.assumed))
    assert not missing, f"{name}: numbers marked assumed without an [assumed.<table>] range: {missing}"
    for key, entry in preset.assumed.items():
        assert entry.key == key and entry.why.strip()
        assert entry.value == parameter_value(preset, key), key
        if entry.values:
            assert entry.value in entry.values and entry.low is None and entry.high is None
        else:
            assert entry.low <= entry.value <= entry.high and entry.low < entry.high


@pytest.mark.parametrize("name", SHIPPED)
def test_each_end_is_a_valid_override_of_that_field_only(name):
    preset = load_preset(name)
    for key, entry in preset.assumed.items():
        for end in entry.ends():
            moved = with_overrides(preset, {key: end})
            assert parameter_value(moved, key) == end, key
            others = [k for k in preset.assumed if k != key]
            assert [parameter_value(moved, k) for k in others] == [parameter_value(preset, k) for k in others]


def test_ends():
    assert Assumed("noise.prnu", 0.01, "x", low=0.003, high=0.03).ends() == (0.003, 0.03)
    assert Assumed("sensor.quantum_efficiency", "fsi", "x", values=("fsi", "bsi")).ends() == ("bsi",)


BASE = """
[sensor]
width = 8
height = 8
pixel_pitch_m = 18.5e-6
fill_factor = 0.22
[photoreceptor]
cutoff_hz = 3000.0
[noise]
prnu = 0.01
dark_current_a = 4e-15
[events]
threshold_on_ln = 0.2
"""


@pytest.mark.parametrize(("assumed", "key", "words"), [
    ('[assumed.noise]\nprnu = { range = [0.02, 0.03], why = "x" }', "assumed.noise.prnu", "outside"),
    ('[assumed.noise]\nprnnu = { range = [0.0, 0.03], why = "x" }', "assumed.noise.prnnu", "did you mean 'prnu'"),
    ('[assumed.noise]\nprnu = { range = [0.0, 0.03], values = [0.01], why = "x" }', "assumed.noise.prnu",
     "exactly one"),
    ('[assumed.noise]\nprnu = { range = [0.0, 0.03], why = " " }', "assumed.noise.prnu", "why"),
    ('[assumed.events]\nthreshold_on_ln = { values = [0.1, 0.3], why = "x" }', "assumed.events.threshold_on_ln",
     "contain"),
    ('[assumed.noise]\nprnu = { range = [0.03, 0.0], why = "x" }', "assumed.noise.prnu", "low < high"),
    ('[assumed.noise]\nprnu = { range = [0.0, 0.03], why = "x", source = "y" }', "assumed.noise.prnu", "unknown key"),
    ('[assumed.stated]\nlatency_s = { range = [0.0, 1.0], why = "x" }', "assumed.stated", "unknown table"),
    ('[assumed.sensor]\nwidth = { range = [1, 10], why = "x" }', "assumed.sensor.width", "cannot be varied"),
])
def test_loader_errors_name_the_key(tmp_path, assumed, key, words):
    path = tmp_path / "p.toml"
    path.write_text(BASE + assumed + "\n")
    with pytest.raises(ConfigError, match=re.escape(words)) as info:
        load_preset(path)
    assert info.value.key == key and info.value.source == str(path)


def test_qualified_overrides_change_exactly_that_field():
    preset = load_preset("davis346")
    aps = with_overrides(preset, {"aps.prnu": 0.02})
    noise = with_overrides(preset, {"noise.prnu": 0.02})
    assert aps.aps.prnu == 0.02 and aps.noise == preset.noise
    assert noise.noise.prnu == 0.02 and noise.aps == preset.aps
    assert with_overrides(preset, {"prnu": 0.02}) == noise  # unqualified: the first owner, as before
    both = with_overrides(preset, {"noise.dc_offset_v": 0.004, "sensor.quantum_efficiency": "bsi"})
    assert both == dataclasses.replace(preset, quantum_efficiency="bsi",
                                       noise=dataclasses.replace(preset.noise, dc_offset_v=0.004))
    with pytest.raises(ConfigError, match="no \\[aps\\]") as info:
        with_overrides(load_preset("dvs128"), {"aps.prnu": 0.02}, where="sensor")
    assert info.value.key == "sensor.aps.prnu"
    with pytest.raises(ConfigError, match="did you mean 'prnu'") as info:
        with_overrides(preset, {"noise.prnnu": 0.02})
    assert info.value.key == "noise.prnnu"
    with pytest.raises(ConfigError, match="no preset table") as info:
        with_overrides(preset, {"nosie.prnu": 0.02})
    assert info.value.key == "nosie.prnu"


def test_the_reference_light_converts_again():
    """``sensor.bandwidth_reference_spectrum`` and ``photoreceptor.cutoff_ref_lux`` move the cutoff's reference
    photocurrent as loading the file with them would."""
    preset = load_preset("dvs128")
    lux = with_overrides(preset, {"photoreceptor.cutoff_ref_lux": 2 * preset.cutoff_ref_lux})
    ratio = lux.photoreceptor.cutoff_ref_photocurrent_a / preset.photoreceptor.cutoff_ref_photocurrent_a
    assert ratio == pytest.approx(2.0, rel=1e-12)
    lamp = with_overrides(preset, {"sensor.bandwidth_reference_spectrum": "A"})
    assert lamp.bandwidth_reference_spectrum == "A"
    assert lamp.photoreceptor.cutoff_ref_photocurrent_a > 1.2 * preset.photoreceptor.cutoff_ref_photocurrent_a
