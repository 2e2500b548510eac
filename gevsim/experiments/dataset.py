"""Synthetic datasets: many randomised emulations, one shard per sequence, resumable.

The config is one ``[dataset]`` table (see ``experiments/dataset_small.toml``):
``sequences``, ``seed``, ``scenes`` and ``sensors`` (names or paths, relative to
the file), ``emulators``, ``duration_s``, ``step_s``, ``chunk_steps``,
``frame_rate_hz``, ``evreal``, ``[dataset.render]`` (overrides of each scene's
render table) and ``[dataset.randomize]``: ``waveforms`` (types to draw from;
omitted: keep each scene's own), ``frequency_hz`` (log-uniform, pwm/sinusoid),
``duty`` (pwm), ``modulation`` (sinusoid), ``mains_hz`` (choice, mains lamps),
``light_scale`` (log-uniform, multiplies all light). A ``scenes`` entry may name a procedural source
(:data:`gevsim.learn.sources.SOURCES`, e.g. ``planar``) set by its own table (``[dataset.planar]``).

Sequence ``i`` draws everything from ``default_rng(SeedSequence([seed, i]))``, in
this order: scene, sensor, then for **every** light group of the scene (in
manifest order) a waveform type, a uniform phase and what that type draws
(:meth:`gevsim.illumination.base.Waveform.drawn`), then the
light scale, then the emulation seed; a source's parameters come from their own stream,
``SeedSequence([seed, i, 1])`` (the same scene whatever lamps are drawn). So any subset of
sequences, in any order, on any executor, gives identical shards.

Output: ``DIR/shards/seq_{i:05d}.h5`` (the emulation), ``DIR/evreal/seq_{i:05d}/``
(DVS events, ground truth tone-mapped to uint8) and, written atomically last as
the done-marker, ``DIR/shards/seq_{i:05d}.json``. A sequence counts as done only
if its marker parses, its shard (and EVREAL folder) exist and the marker's
config, scene file contents and gevsim version equal the ones it would run now
(:func:`finished`); otherwise it is redone from scratch. A sequence with fewer than
two DVS events gets no EVREAL folder (EVREAL cannot load one): its marker says why
under ``evreal_skipped``.
``DIR/dataset.json`` lists the done ones.
"""

from __future__ import annotations

import concurrent.futures as cf
import functools
import json
import logging
import math
import os
import shutil
import time
import tomllib
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from gevsim import __version__
from gevsim._validate import FieldError, real_list
from gevsim.config import TomlReader, load_table, resolve_relative
from gevsim.emulation.config import MAX_LIGHT_SCALE, EmulationConfig
from gevsim.emulation.emulators import EMULATORS
from gevsim.errors import ConfigError, check_keys, suggest
from gevsim.experiments.executors import run_all
from gevsim.experiments.parts import Work, merge_parts
from gevsim.illumination.base import MAX_FREQUENCY_HZ, log_uniform
from gevsim.illumination.spec import RANDOM_WAVEFORMS, random_spec
from gevsim.io import EventReader, atomic_write_text, exclusive, sweep_stale
from gevsim.io.evreal import MIN_EVENTS, export_evreal_from
from gevsim.render.quality import check_render_overrides
from gevsim.resources import MAX_SEQUENCES
from gevsim.timebase import TimeGrid

log = logging.getLogger(__name__)

KEYS = ("sequences", "seed", "scenes", "sensors", "emulators", "duration_s", "step_s", "chunk_steps",
        "frame_rate_hz", "evreal", "aps", "render", "randomize", "planar")


@dataclass(frozen=True)
class Randomize:
    """Ranges drawn per sequence; ``(low, high)`` pairs, ``mains_hz`` a set to choose from."""

    waveforms: tuple[str, ...] = ()  # empty: keep each scene's own waveforms
    frequency_hz: tuple[float, float] = (100.0, 2000.0)
    duty: tuple[float, float] = (0.1, 0.9)
    modulation: tuple[float, float] = (0.2, 1.0)
    mains_hz: tuple[float, ...] = (50.0, 60.0)
    light_scale: tuple[float, float] = (1.0, 1.0)


@dataclass(frozen=True)
class DatasetConfig:
    scenes: tuple[str, ...]
    sequences: int = 1
    seed: int = 0
    sensors: tuple[str, ...] = ("davis346",)
    emulators: tuple[str, ...] = ("dvs", "gradient", "gradient_rc")
    time: TimeGrid = TimeGrid()
    evreal: bool = False
    aps: bool = False  # also APS frames (the complementary filter's input; needs the sensors' [aps])
    render: dict = field(default_factory=dict)
    randomize: Randomize = Randomize()
    source_options: dict = field(default_factory=dict)  # procedural source -> its options ([dataset.<source>])
    source: str = ""
    text: str = ""


def _names(r: TomlReader, table: dict, where: str, key: str, default, check, *, base: Path | None = None,
           empty: bool = False) -> tuple[str, ...]:
    """A list of names, each passed to ``check`` (which raises ConfigError); .toml paths resolved."""
    value = table.get(key, default)
    if not isinstance(value, list) or not (value or empty) or not all(isinstance(v, str) for v in value):
        r.fail(f"{where}.{key}", f"expected a non-empty list of names, got {value!r}")
    out = []
    for v in value:
        if base is not None:
            v = resolve_relative(v, base)
        try:
            check(v)
        except ConfigError as exc:
            r.fail(f"{where}.{key}", str(exc))
        out.append(v)
    return tuple(out)


def _one_of(choices: tuple[str, ...], what: str):
    def check(name: str) -> None:
        if name not in choices:
            raise ConfigError(f"unknown {what} {name!r}{suggest(name, choices)}; choose from {', '.join(choices)}")
    return check


def _range(r: TomlReader, table: dict, key: str, default, *, high=None):
    value = table.get(key, list(default))
    ok = (isinstance(value, list) and len(value) == 2
          and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value))
    if not ok or not 0 < value[0] <= value[1] or (high is not None and value[1] > high):
        bound = f" <= {high}" if high is not None else ""
        r.fail(f"dataset.randomize.{key}", f"expected [low, high] with 0 < low <= high{bound}, got {value!r}")
    return (float(value[0]), float(value[1]))


def _randomize(r: TomlReader, table: dict) -> Randomize:
    where = "dataset.randomize"
    check_keys(table, list(Randomize.__dataclass_fields__), source=r.source, where=where)
    waves = _names(r, table, where, "waveforms", [], _one_of(RANDOM_WAVEFORMS, "waveform type"), empty=True)
    try:
        mains = real_list(table.get("mains_hz", [50.0, 60.0]), "mains_hz", positive=True)
    except FieldError as err:
        r.fail(f"{where}.mains_hz", str(err))
    if max(mains) > MAX_FREQUENCY_HZ:
        r.fail(f"{where}.mains_hz", f"{max(mains)!r} is above {MAX_FREQUENCY_HZ:g}")
    d = Randomize()
    return Randomize(waves, _range(r, table, "frequency_hz", d.frequency_hz, high=MAX_FREQUENCY_HZ),
                     _range(r, table, "duty", d.duty, high=1.0), _range(r, table, "modulation", d.modulation, high=1.0),
                     mains, _range(r, table, "light_scale", d.light_scale, high=MAX_LIGHT_SCALE))


def load_dataset_config(path: str | Path) -> DatasetConfig:
    """Read and validate a dataset config; errors name the file and key."""
    from gevsim.pixel import load_preset
    from gevsim.render import load

    path = Path(path)
    raw, r = load_table(path, what="dataset config", tables=("dataset",))
    ds = r.table(raw, "dataset")
    check_keys(ds, KEYS, source=r.source, where="dataset")
    emulators = _names(r, ds, "dataset", "emulators", list(DatasetConfig.emulators),
                       _one_of(tuple(EMULATORS), "emulator"))
    render = r.table(ds, "render", "dataset.")
    check_render_overrides(render, r, "dataset.render")
    evreal, aps = ds.get("evreal", False), ds.get("aps", False)
    for key, flag in (("evreal", evreal), ("aps", aps)):
        if not isinstance(flag, bool):
            r.fail(f"dataset.{key}", f"expected true or false, got {flag!r}")
    sources = _sources()
    config = DatasetConfig(
        scenes=_names(r, ds, "dataset", "scenes", None, lambda v: None if v in sources else load(v), base=path.parent),
        sequences=r.number(ds, "sequences", "dataset", positive=True, integer=True, maximum=MAX_SEQUENCES),
        seed=r.number(ds, "seed", "dataset", 0, minimum=0, integer=True),
        sensors=_names(r, ds, "dataset", "sensors", ["davis346"], load_preset, base=path.parent),
        emulators=emulators,
        time=TimeGrid.from_section(ds, source=r.source, where="dataset"),
        evreal=evreal, aps=aps, render=dict(render), randomize=_randomize(r, r.table(ds, "randomize", "dataset.")),
        source_options={k: s.options(r.table(ds, k, "dataset."), r, f"dataset.{k}") for k, s in sources.items()},
        source=str(path), text=path.read_text())
    if evreal and ("dvs" not in emulators or config.time.frame_rate_hz <= 0):
        r.fail("dataset.evreal", "needs 'dvs' in dataset.emulators and frame_rate_hz > 0 (ground-truth frames)")
    return config


def _waveform(rng: np.random.Generator, rz: Randomize) -> dict:
    """One light group's random waveform: its type, a phase, then what the type draws
    (:meth:`gevsim.illumination.base.Waveform.drawn`), in this order."""
    kind = rz.waveforms[int(rng.integers(len(rz.waveforms)))]
    phase = float(rng.uniform(0.0, 2.0 * math.pi))
    return random_spec(kind, rng, rz, phase_rad=phase)


def _sources() -> dict:
    from gevsim.learn.sources import SOURCES

    return SOURCES


def scene_sha256(scene: str) -> str:
    """The digest of a scene's files (:func:`gevsim.render.inputs.scene_digest`), or of a source's code."""
    from gevsim.render.inputs import scene_digest

    source = _sources().get(scene)
    return source.digest() if source is not None else scene_digest(scene)


@functools.lru_cache(maxsize=64)
def _group_names(scene: str) -> tuple[str, ...]:
    from gevsim.render import load

    source = _sources().get(scene)
    return source.group_names if source is not None else load(scene).group_names


def sequence_parameters(config: DatasetConfig, index: int) -> dict:
    """The random parameters of sequence ``index`` (JSON-ready; depends on nothing else)."""
    if not 0 <= index < config.sequences:
        raise ValueError(f"sequence index {index} outside [0, {config.sequences})")
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, index]))
    scene = config.scenes[int(rng.integers(len(config.scenes)))]
    sensor = config.sensors[int(rng.integers(len(config.sensors)))]
    groups = _group_names(scene) if config.randomize.waveforms else ()
    waveforms = {g: _waveform(rng, config.randomize) for g in groups}
    light_scale = log_uniform(rng, config.randomize.light_scale)
    params = {"index": index, "scene": scene, "sensor": sensor, "waveforms": waveforms, "light_scale": light_scale,
              "seed": int(rng.integers(2**31))}
    source = _sources().get(scene)
    if source is not None:  # its own stream: the same planes and motions whatever the lamps drew
        own = np.random.default_rng(np.random.SeedSequence([config.seed, index, 1]))
        params["source"] = source.draw(own, config.source_options.get(scene))
    return params


def sequence_config(config: DatasetConfig, params: dict) -> EmulationConfig:
    """The emulation config of one sequence: the dataset's base config with its drawn parameters."""
    base = EmulationConfig(scene=config.scenes[0], sensor=config.sensors[0], emulators=config.emulators,
                           **asdict(config.time), render=dict(config.render), source=config.source, aps=config.aps)
    return replace(base, scene=params["scene"], sensor=params["sensor"], seed=params["seed"],
                   light_scale=params["light_scale"], group_waveform=dict(params["waveforms"]))


def _paths(out_dir, index: int) -> tuple[Path, Path, Path]:
    out, name = Path(out_dir), f"seq_{index:05d}"
    return out / "shards" / f"{name}.json", out / "shards" / f"{name}.h5", out / "evreal" / name


def finished(config: DatasetConfig, out_dir: str | os.PathLike, index: int, *,
             digests: dict[tuple[str, str], str] | None = None) -> dict | None:
    """The done-marker of sequence ``index`` if it is finished for this config, else None.

    Finished means: the marker parses, names the config this sequence would run now, the same
    contents of its scene's files (:func:`gevsim.render.inputs.scene_digest`), of its sensor preset
    (:func:`gevsim.pixel.presets.preset_digest`) and this gevsim version, and the shard (and EVREAL folder)
    exist. ``digests`` (a dict kept across calls) keeps the scenes' and presets' digests: one hash of each
    file per check of many sequences.
    """
    from gevsim.pixel.presets import preset_digest

    def digest(what: str, name: str, fn: Callable[[str], str]) -> str:
        if digests is None:
            return fn(name)
        if (what, name) not in digests:
            digests[what, name] = fn(name)
        return digests[what, name]

    marker, shard, evreal = _paths(out_dir, index)
    try:
        record = json.loads(marker.read_text())
        params = sequence_parameters(config, index)
        same = (tomllib.loads(record["config_toml"]) == tomllib.loads(sequence_config(config, params).to_toml())
                and record["gevsim_version"] == __version__
                and record["parameters"].get("source") == params.get("source")
                and record["scene_sha256"] == digest("scene", params["scene"], scene_sha256)
                and record["sensor_sha256"] == digest("sensor", params["sensor"], preset_digest))
    except (OSError, ValueError, KeyError, TypeError):
        return None
    evreal_done = evreal.is_dir() or not config.evreal or record.get("evreal_skipped")
    return record if same and shard.is_file() and evreal_done else None


def _clear(out_dir, index: int) -> None:
    """Remove every trace of sequence ``index``, the marker first (and leftover temp files)."""
    marker, shard, evreal = _paths(out_dir, index)
    marker.unlink(missing_ok=True)
    shard.unlink(missing_ok=True)
    shutil.rmtree(evreal, ignore_errors=True)
    for folder, stem in ((marker.parent, shard.stem), (evreal.parent, evreal.name)):
        for tmp in folder.glob(f".{stem}.*") if folder.is_dir() else ():
            shutil.rmtree(tmp, ignore_errors=True) if tmp.is_dir() else tmp.unlink(missing_ok=True)


def _export_evreal(shard: Path, folder: Path, params: dict) -> str | None:
    """Write the sequence's EVREAL folder; returns why it was not written (too few DVS events), else None."""
    with EventReader(shard) as r:
        if r.count("events") < MIN_EVENTS:
            reason = f"{r.count('events')} DVS events: EVREAL cannot load a sequence with fewer than {MIN_EVENTS}"
            log.warning("sequence %d: %s; %s not written", params["index"], reason, folder)
            return reason
    export_evreal_from(shard, folder, extra_metadata={"parameters": params})
    return None


def run_sequence(config: DatasetConfig, out_dir: str, index: int, *, cache_dir: str | None = None) -> dict:
    """Make sequence ``index`` unless finished (picklable: what executors run). Returns a small dict."""
    from gevsim.emulation.driver import run
    from gevsim.pixel.presets import preset_digest

    done = finished(config, out_dir, index)
    if done is not None:
        return {"index": index, "status": "skipped", "counts": done["counts"], "seconds": 0.0}
    start = time.perf_counter()
    _clear(out_dir, index)
    marker, shard, evreal = _paths(out_dir, index)
    params = sequence_parameters(config, index)
    emulation = sequence_config(config, params)
    scene_sha = scene_sha256(params["scene"])  # before the run: an edit during it makes the next run redo it
    sensor_sha256 = preset_digest(params["sensor"])
    source = _sources().get(params["scene"])
    setup = source.setup(emulation, params["source"]) if source is not None else None
    summary = run(emulation, shard, cache_dir=cache_dir, setup=setup)
    skipped = _export_evreal(shard, evreal, params) if config.evreal else None
    seconds = time.perf_counter() - start
    record = {"index": index, "parameters": params, "config_toml": emulation.to_toml(), "counts": summary.counts,
              "frames": summary.frames, "width": summary.width, "height": summary.height,
              "shard": str(shard.relative_to(Path(out_dir))), "seconds": seconds, "gevsim_version": __version__,
              "scene_sha256": scene_sha, "sensor_sha256": sensor_sha256,
              "evreal": str(evreal.relative_to(Path(out_dir))) if config.evreal and not skipped else None}
    if skipped:
        record["evreal_skipped"] = skipped
    atomic_write_text(marker, json.dumps(record, indent=1))  # last: the done-marker
    return {"index": index, "status": "done", "counts": summary.counts, "seconds": seconds}


def generate(config: DatasetConfig, out_dir: str | os.PathLike, *, executor: cf.Executor | None = None,
             indices: Iterable[int] | None = None, cache_dir: str | os.PathLike | None = None,
             progress: Callable[[int, int], None] | None = None) -> dict:
    """Make the sequences ``indices`` (default: all) that are not finished, then ``dataset.json``.

    ``executor`` None runs them here, one after another; ``progress(done, total)``
    is called as each completes (finished ones count at once). One run at a
    time per ``out_dir``: a second one (another process) is refused with a
    :class:`~gevsim.errors.ConfigError` naming the folder (:func:`gevsim.io.exclusive`).
    What ``--part`` runs finished beside it (``OUT.parts``, :mod:`gevsim.experiments.parts`) is merged in first.
    Returns ``out``, ``sequences``, ``done`` (made now), ``skipped``, ``counts``
    (events per stream over ``indices``), ``events`` (their sum), ``seconds`` and ``merged`` (sequences moved
    in from the parts).
    """
    out = Path(out_dir)
    with exclusive(out, what="dataset", kind="dataset"):  # one run at a time per folder: a second one is refused
        merged = merge_parts(out, dataset_work(config))
        summary = _generate(config, out, executor=executor, indices=indices, cache_dir=cache_dir, progress=progress)
        return {**summary, "merged": merged["moved"]}


def dataset_work(config: DatasetConfig) -> Work:
    """A dataset's sequences as the work a merge of ``--part`` folders moves (:mod:`gevsim.experiments.parts`)."""
    digests: dict = {}

    def files(index: int) -> tuple[str, ...]:
        marker, shard, evreal = _paths("", index)
        return (str(evreal), str(shard), str(marker))

    return Work("dataset", config.sequences, lambda folder, i: finished(config, folder, i, digests=digests) is not None,
                files)


def _generate(config: DatasetConfig, out: Path, *, executor, indices, cache_dir, progress, index: bool = True) -> dict:
    """Make ``indices`` in ``out`` (locked by the caller); ``index``: write ``dataset.json`` (not in a part)."""
    start = time.perf_counter()
    sweep_stale(out)  # what killed runs left half-written (stages nobody holds)
    indices = list(dict.fromkeys(range(config.sequences) if indices is None else indices))
    for i in indices:
        sequence_parameters(config, i)  # validates the index
    digests: dict = {}
    todo = [i for i in indices if finished(config, out, i, digests=digests) is None]
    total, done = len(indices), len(indices) - len(todo)
    cache = None if cache_dir is None else str(cache_dir)
    results = run_all(run_sequence, [((config, str(out), i), {"cache_dir": cache}) for i in todo], executor=executor,
                      progress=progress, done=done, total=total)
    records = write_index(config, out) if index else [
        r for r in (finished(config, out, i, digests=digests) for i in indices) if r is not None]
    counts: dict[str, int] = {}
    wanted = set(indices)
    for r in (x for x in records if x["index"] in wanted):
        for k, v in r["counts"].items():
            counts[k] = counts.get(k, 0) + v
    computed = sum(r["status"] == "done" for r in results)
    return {"out": str(out), "sequences": total, "done": computed, "skipped": total - computed, "counts": counts,
            "events": sum(counts.values()), "seconds": time.perf_counter() - start}


def write_index(config: DatasetConfig, out: Path) -> list[dict]:
    """Write ``dataset.json`` (the finished sequences' records, ``complete`` when they are all there) into
    ``out`` (locked by the caller); returns the records."""
    digests: dict = {}
    records = [r for r in (finished(config, out, i, digests=digests) for i in range(config.sequences))
               if r is not None]
    atomic_write_text(out / "dataset.json", json.dumps({
        "gevsim_version": __version__, "source": config.source, "config_toml": config.text,
        "complete": len(records) == config.sequences, "sequences": records}, indent=1))
    return records
