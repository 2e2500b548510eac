"""docs/config.md is the reference of every configuration file a user writes (issue 12).

Every key the loaders accept (the key tuples of each loader, the fields of the parameter
dataclasses, the waveform registry and its fields, the registries of emulators, methods,
samplers and executors) and every flag of ``gevsim render/emulate/study/dataset`` must appear
on the page as `` `key` ``, so the page cannot drift from the code; and its examples load.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import shutil
import tomllib
from pathlib import Path

import pytest

from gevsim.emulation.config import EMULATION_KEYS, EmulationConfig, load_config
from gevsim.emulation.config import TABLES as EMULATION_TABLES
from gevsim.emulation.emulators import EMULATORS
from gevsim.evaluation.methods import METHODS
from gevsim.experiments.dataset import KEYS as DATASET_KEYS
from gevsim.experiments.dataset import RANDOM_WAVEFORMS, Randomize, load_dataset_config
from gevsim.experiments.executors import EXECUTORS
from gevsim.experiments.study import AXES, REPORT_KEYS, SENSOR_AXES, STUDY_KEYS, load_study
from gevsim.experiments.study import TABLES as STUDY_TABLES
from gevsim.experiments.study import WAVEFORMS as SWEEP_WAVEFORMS
from gevsim.experiments.study_run import check_study_scenes
from gevsim.experiments.variations import SENSITIVITY_KEYS, TRADEOFF_KEYS
from gevsim.illumination.spec import WAVEFORMS
from gevsim.optics.spec import OPTICS_KEYS
from gevsim.pixel.aps import ApsParams
from gevsim.pixel.params import EventParams, NoiseParams, PhotoreceptorParams
from gevsim.pixel.presets import SENSOR_KEYS, load_preset, with_overrides
from gevsim.pixel.presets import TABLES as PRESET_TABLES
from gevsim.render.backend import FLAVOURS
from gevsim.render.manifest import (
    CAMERA_KEY_KEYS,
    CAMERA_KEYS,
    GROUP_KEYS,
    MOTION_KEY_KEYS,
    MOTION_KEYS,
    SCENE_KEYS,
    SEQUENCE_KEYS,
    load,
)
from gevsim.render.manifest import TABLES as MANIFEST_TABLES
from gevsim.render.quality import NOISE_METRICS, OVERRIDE_KEYS, QUALITY_KEYS, RENDER_KEYS, SAMPLERS
from gevsim.timebase import TimeGrid

ROOT = Path(__file__).parents[1]
PAGE = ROOT / "docs" / "config.md"
TEXT = PAGE.read_text()
#: Everything the page writes as inline code.
CODE = set(re.findall(r"`([^`\n]+)`", TEXT))


def names(cls) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls))


def emulation_subtables() -> dict[str, tuple[str, ...]]:
    """The keys of the tables an emulation config has besides [emulation] and [render] (their loader
    checks them with inline tuples), as its own writer, ``EmulationConfig.to_toml``, spells them."""
    config = EmulationConfig(scene="office", group_scale={"g": 0.5}, group_waveform={"g": {"type": "dc"}},
                             sensor_overrides={"cutoff_hz": 1.0})
    written = tomllib.loads(config.to_toml())
    keys = {f"[{t}]": tuple(written[t]) for t in ("gradient", "csdvs", "light")}
    keys["[light.groups.<name>]"] = tuple(written["light"]["groups"]["g"])
    return keys


#: Tables, documented as `name` or `[name]`.
TABLES = {
    "scene manifest tables": MANIFEST_TABLES,
    "emulation config tables": EMULATION_TABLES,
    "study config tables": STUDY_TABLES,
    "dataset config tables": ("dataset",),
    "sensor preset tables": PRESET_TABLES,
}

#: Keys, values of registries and flags, documented as `name`.
KEYS = {
    "manifest [scene]": SCENE_KEYS,
    "manifest [render]": RENDER_KEYS + QUALITY_KEYS + OVERRIDE_KEYS,
    "manifest [render] sampler": SAMPLERS,
    "manifest [render] noise_metric": NOISE_METRICS,
    "manifest [render] flavour": FLAVOURS,
    "manifest [sequence]": SEQUENCE_KEYS,
    "manifest [camera]": CAMERA_KEYS,
    "manifest camera keyframes": CAMERA_KEY_KEYS,
    "manifest [[motion]]": MOTION_KEYS,
    "manifest motion keyframes": MOTION_KEY_KEYS,
    "manifest [light_groups.<name>]": GROUP_KEYS,
    "manifest [optics]": OPTICS_KEYS + ("wavelength_nm",),
    "waveform types": tuple(WAVEFORMS),
    **{f"waveform {name!r}": names(cls) for name, cls in WAVEFORMS.items()},
    "emulation [emulation]": EMULATION_KEYS,
    "time grid (TimeGrid)": names(TimeGrid),
    "emulators": tuple(EMULATORS),
    **{f"emulation {table}": keys for table, keys in emulation_subtables().items()},
    "study [study]": STUDY_KEYS,
    "study [sweep]": AXES + SENSOR_AXES,
    "study [sweep] waveform": SWEEP_WAVEFORMS,
    "study [report]": REPORT_KEYS,
    "study [sensitivity]": SENSITIVITY_KEYS,
    "study [tradeoff]": TRADEOFF_KEYS,
    "reconstruction methods": tuple(METHODS),
    "executors": tuple(EXECUTORS),
    "dataset [dataset]": DATASET_KEYS,
    "dataset [dataset.randomize]": names(Randomize),
    "dataset randomize waveforms": RANDOM_WAVEFORMS,
    "preset [sensor]": SENSOR_KEYS,
    "preset [photoreceptor]": names(PhotoreceptorParams) + ("cutoff_ref_lux",),
    "preset [noise]": names(NoiseParams),
    "preset [events]": names(EventParams),
    "preset [aps]": names(ApsParams),
    "unit suffixes": ("_s", "_hz", "_ln", "_lux", "_a"),
}


def cli_flags() -> dict[str, tuple[str, ...]]:
    """The long options of the subcommands that read configs, from the CLI's own parser."""
    from gevsim.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {f"gevsim {name} flags": tuple(opt for action in sub.choices[name]._actions for opt in action.option_strings
                                           if opt.startswith("--") and opt != "--help")
            for name in ("render", "emulate", "study", "dataset")}


@pytest.mark.parametrize("group", sorted(TABLES))
def test_every_table_is_documented(group):
    missing = [t for t in TABLES[group] if t not in CODE and f"[{t}]" not in CODE]
    assert not missing, f"{PAGE.relative_to(ROOT)} does not document the {group} {missing}"


@pytest.mark.parametrize("group", sorted(KEYS))
def test_every_key_is_documented(group):
    missing = [k for k in KEYS[group] if k not in CODE]
    assert not missing, f"{PAGE.relative_to(ROOT)} does not document the {group}: {missing} (write them as `key`)"


@pytest.mark.parametrize("command", sorted(cli_flags()))
def test_every_flag_is_documented(command):
    missing = [f for f in cli_flags()[command] if f not in CODE]
    assert not missing, f"{PAGE.relative_to(ROOT)} does not document the {command}: {missing}"


EXAMPLES = dict(re.findall(r"^### Example: `([^`]+)`\n\n```toml\n(.*?)^```", TEXT, flags=re.M | re.S))


def test_one_example_per_file_kind():
    assert set(EXAMPLES) == {"scenes/office.toml", "experiments/office_small.toml", "experiments/flicker.toml",
                             "experiments/dataset_small.toml", "noise/ideal.toml"}


def test_examples_load(tmp_path):
    """Each example is a valid file of its kind (written next to what it refers to)."""
    def write(name: str) -> Path:
        path = tmp_path / Path(name).name
        path.write_text(EXAMPLES[name])
        return path

    shutil.copy(ROOT / "scenes" / "office.py", tmp_path / "office.py")
    scene = load(write("scenes/office.toml"))
    assert scene.group_names == ("ceiling", "daylight")

    emulation = load_config(write("experiments/office_small.toml"))
    with_overrides(load_preset(emulation.sensor), emulation.sensor_overrides, source=emulation.source)
    assert set(emulation.group_waveform) <= set(load(emulation.scene).group_names)

    check_study_scenes(load_study(write("experiments/flicker.toml")))
    load_dataset_config(write("experiments/dataset_small.toml"))
    assert load_preset(write("noise/ideal.toml")).aps is not None


def test_readme_and_cli_point_at_the_page():
    from gevsim.cli import build_parser

    assert "docs/config.md" in (ROOT / "README.md").read_text()
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("emulate", "study", "dataset"):
        assert "docs/config.md" in sub.choices[command].format_help(), command
