"""Dataset generation: per-sequence determinism, executors agree, resumable shards, EVREAL folders, config errors,
array-job parts (--part, --merge) equal to a single run bit for bit."""

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from conftest import textured_scene

import gevsim.experiments.dataset as dataset_mod
from gevsim.cli import main
from gevsim.errors import ConfigError
from gevsim.experiments.dataset import finished, generate, load_dataset_config, sequence_parameters
from gevsim.experiments.dataset_parts import generate_part
from gevsim.experiments.executors import make_executor
from gevsim.experiments.parts import Part, parts_root
from gevsim.io import EventReader, import_evreal
from gevsim.io.evreal import EVENT_FILES, IMAGE_FILES, METADATA
from gevsim.io.mark import MARK, open_mark
from gevsim.io.staging import LOCK_NAME

DATA = Path(__file__).parents[1] / "data"
N = 3


def write_config(folder: Path, name="dataset.toml", **changes) -> Path:
    ds = {"sequences": N, "seed": 7, "scenes": [str(DATA / "card.toml")], "sensors": ["davis346", "dvs128"],
          "emulators": ["dvs", "gradient", "gradient_rc"], "duration_s": 2e-3, "step_s": 1e-4,
          "frame_rate_hz": 2000.0, "evreal": True, "render": {"width": 24, "height": 18, "spp": 2},
          "randomize": {"waveforms": ["pwm", "fluorescent", "sodium_hid", "sinusoid"],
                        "frequency_hz": [100.0, 2000.0], "duty": [0.1, 0.9], "mains_hz": [50.0, 60.0],
                        "light_scale": [0.5, 2.0]}}
    ds.update(changes)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(tomli_w.dumps({"dataset": ds}))
    return path


def shard(out: Path, i: int) -> Path:
    return out / "shards" / f"seq_{i:05d}.h5"


def marker(out: Path, i: int) -> Path:
    return out / "shards" / f"seq_{i:05d}.json"


def contents(path: Path) -> dict:
    with EventReader(path) as r:
        data = {s: r.read(s) for s in r.streams}
        for name in r.frame_names:
            data[name] = r.frames(name)
    return data


def assert_same_shard(a: Path, b: Path) -> None:
    ca, cb = contents(a), contents(b)
    assert ca.keys() == cb.keys()
    for key in ca:
        if isinstance(ca[key], tuple):  # frames: (images, t_us)
            for x, y in zip(ca[key], cb[key]):
                np.testing.assert_array_equal(x, y)
        else:
            np.testing.assert_array_equal(ca[key], cb[key])


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """All N sequences made in this process (no executor); returns (config, out, cache, summary)."""
    base = tmp_path_factory.mktemp("dataset")
    config = load_dataset_config(write_config(base))
    out, cache = base / "ref", base / "cache"
    summary = generate(config, out, cache_dir=cache)
    return config, out, cache, summary


def test_full_run_makes_every_sequence_with_events(reference):
    config, out, _, summary = reference
    assert summary["done"] == N and summary["skipped"] == 0
    index = json.loads((out / "dataset.json").read_text())
    assert index["complete"] and [s["index"] for s in index["sequences"]] == list(range(N))
    for i in range(N):
        record = json.loads(marker(out, i).read_text())
        assert record["parameters"] == sequence_parameters(config, i)
        with EventReader(shard(out, i)) as r:
            assert {s: len(r.read(s)) for s in r.streams} == record["counts"]
    assert summary["events"] == sum(sum(s["counts"].values()) for s in index["sequences"]) > 0
    # the draws differ between sequences (seed, waveform phase at least)
    assert len({sequence_parameters(config, i)["seed"] for i in range(N)}) == N


def test_a_sequence_alone_equals_the_same_sequence_of_a_full_run(reference, tmp_path):
    config, out, cache, _ = reference
    summary = generate(config, tmp_path / "alone", indices=[2, 1], cache_dir=cache)
    assert summary["done"] == 2 and not marker(tmp_path / "alone", 0).exists()
    for i in (1, 2):
        assert_same_shard(shard(out, i), shard(tmp_path / "alone", i))


@pytest.mark.slow
def test_process_pool_and_dask_give_the_same_shards(reference, tmp_path):
    config, out, cache, _ = reference
    with make_executor("local", workers=2) as pool:
        local = generate(config, tmp_path / "local", executor=pool, cache_dir=cache)
    with make_executor("dask", workers=2) as client:
        dask = generate(config, tmp_path / "dask", executor=client, cache_dir=cache)
    assert local["done"] == dask["done"] == N
    assert local["counts"] == dask["counts"] == reference[3]["counts"]
    for i in range(N):
        assert_same_shard(shard(out, i), shard(tmp_path / "local", i))
        assert_same_shard(shard(out, i), shard(tmp_path / "dask", i))


def test_resume_recomputes_only_what_is_not_finished(reference, tmp_path):
    config, ref, cache, _ = reference
    out = tmp_path / "out"
    shutil.copytree(ref, out)
    stamp = lambda i: (marker(out, i).stat().st_mtime_ns, marker(out, i).read_bytes())  # noqa: E731
    before = {i: stamp(i) for i in range(N)}

    again = generate(config, out, cache_dir=cache)
    assert (again["done"], again["skipped"]) == (0, N)
    assert {i: stamp(i) for i in range(N)} == before

    marker(out, 1).unlink()
    redo = generate(config, out, cache_dir=cache)
    assert (redo["done"], redo["skipped"]) == (1, N - 1)
    assert stamp(0) == before[0] and stamp(2) == before[2] and stamp(1) != before[1]
    assert_same_shard(shard(ref, 1), shard(out, 1))

    # a killed run: shard without marker, plus a writer's leftover temp file, and the mark left open
    marker(out, 2).unlink()
    open_mark(out, "dataset")
    leftover = out / "shards" / ".seq_00002.h5.x1y2z3.tmp"
    leftover.write_bytes(b"partial")
    assert finished(config, out, 2) is None and finished(config, out, 0) is not None
    redo = generate(config, out, cache_dir=cache)
    assert (redo["done"], redo["skipped"]) == (1, N - 1)
    assert not leftover.exists() and marker(out, 2).exists()
    assert_same_shard(shard(ref, 2), shard(out, 2))

    # a marker made with another config is not a finished sequence for this one
    other = load_dataset_config(write_config(tmp_path, "other.toml", step_s=5e-5))
    assert finished(other, out, 0) is None


@pytest.mark.slow
def test_cli_resumes_and_reports(reference, tmp_path, capsys):
    config, ref, cache, _ = reference
    out = tmp_path / "out"
    shutil.copytree(ref, out)
    marker(out, 0).unlink()
    assert main(["dataset", config.source, "--out", str(out), "--cache", str(cache), "--workers", "1", "-q"]) == 0
    err = capsys.readouterr().err
    assert f"{N} sequences: 1 made, {N - 1} already done" in err
    assert_same_shard(shard(ref, 0), shard(out, 0))


def test_evreal_folders_import_back(reference):
    _, out, _, _ = reference
    assert len(os.listdir(out / "evreal")) >= 2
    for i in range(N):
        folder = out / "evreal" / f"seq_{i:05d}"
        record = json.loads(marker(out, i).read_text())
        if record["counts"]["events"] < 2:  # (here seq 1, dvs128, with 1 event) EVREAL cannot load that
            assert record["evreal"] is None and "fewer than 2" in record["evreal_skipped"]
            assert not folder.exists()
            continue
        assert "evreal_skipped" not in record
        assert sorted(os.listdir(folder)) == sorted(EVENT_FILES + IMAGE_FILES + (METADATA,))
        events, images, t_us, width, height = import_evreal(folder)
        with EventReader(shard(out, i)) as r:
            np.testing.assert_array_equal(events, r.read("events"))
            log_frames, frame_t = r.frames("log_photocurrent")
        assert (width, height) == (24, 18) and images.dtype == np.uint8 and images.shape == log_frames.shape
        np.testing.assert_array_equal(t_us, frame_t)
        assert images.max() > images.min()  # tone-mapped, not flat
        meta = json.loads((folder / METADATA).read_text())
        assert meta["parameters"]["index"] == i and len(meta["tone_map_ln"]) == 2


@pytest.mark.parametrize("changes, key, text", [
    ({"sequence": 3}, "dataset.sequence", "did you mean 'sequences'"),
    ({"scenes": []}, "dataset.scenes", "non-empty list"),
    ({"sequences": -2}, "dataset.sequences", "sequences must be an integer in 1..1000000, got -2"),
    ({"scenes": ["ofice"]}, "dataset.scenes", "did you mean 'office'"),
    ({"randomize": {"waveforms": ["pwn"]}}, "dataset.randomize.waveforms", "did you mean 'pwm'"),
    ({"randomize": {"duty": [0.5, 1.5]}}, "dataset.randomize.duty", "0 < low <= high <= 1.0"),
    ({"emulators": ["gradient"]}, "dataset.evreal", "needs 'dvs'"),
])
def test_bad_config_names_file_and_key(tmp_path, changes, key, text):
    path = write_config(tmp_path, **changes)
    with pytest.raises(ConfigError) as info:
        load_dataset_config(path)
    assert info.value.key == key and info.value.source == str(path) and text in str(info.value)


def test_cli_bad_config_exits_2_without_traceback(tmp_path, capsys):
    path = write_config(tmp_path, sequences=-1)
    assert main(["dataset", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "dataset.sequences" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_an_edited_scene_file_or_another_version_redoes_the_sequence(tmp_path, monkeypatch):
    scene = textured_scene(tmp_path / "scene")
    config = load_dataset_config(write_config(tmp_path, sequences=1, scenes=[str(scene)], evreal=False,
                                              sensors=["davis346"]))
    out = tmp_path / "out"
    assert generate(config, out, cache_dir=tmp_path / "c")["done"] == 1
    assert generate(config, out, cache_dir=tmp_path / "c")["done"] == 0
    with EventReader(shard(out, 0)) as r:
        before = r.frames("log_photocurrent")[0]
    textured_scene(tmp_path / "scene", card=0.05, backdrop=0.05)
    assert finished(config, out, 0) is None
    assert generate(config, out, cache_dir=tmp_path / "c")["done"] == 1
    with EventReader(shard(out, 0)) as r:
        assert r.frames("log_photocurrent")[0].mean() < before.mean() - 1.0  # darker textures: ln(20x) lower
    assert finished(config, out, 0) is not None
    monkeypatch.setattr(dataset_mod, "__version__", "999.0")
    assert finished(config, out, 0) is None


def test_a_rerun_removes_what_killed_runs_left(reference, tmp_path):
    """Stages nobody holds (kill -9 runs no cleanup) are swept at the start of a rerun, finished or not."""
    config, ref, cache, _ = reference
    out = tmp_path / "out"
    shutil.copytree(ref, out)
    left = [out / "shards" / ".seq_00001.h5.gevsim-k1ll3d00.tmp", out / "evreal" / ".seq_00001.gevsim-k1ll3d00.tmp"]
    left[0].write_bytes(b"half an HDF5 file")
    left[1].mkdir()
    for p in left:
        os.utime(p, (p.stat().st_mtime - 60,) * 2)
    assert generate(config, out, cache_dir=cache)["done"] == 0
    assert not any(p.exists() for p in left) and not list(out.rglob("*gevsim-*"))


def test_a_second_dataset_run_on_the_same_folder_is_refused(tmp_path, capsys):
    import subprocess
    import sys

    holder_code = ("import sys, time\nfrom gevsim.io import exclusive\nwith exclusive(sys.argv[1], what='dataset'):\n"
                   "    print('holding', flush=True)\n    time.sleep(600)\n")
    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", holder_code, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "holding"
        assert main(["dataset", str(write_config(tmp_path)), "--out", str(out), "--workers", "1", "-q"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{out}: another gevsim dataset is writing into this folder" in err
        assert sorted(p.name for p in out.iterdir()) == [".gevsim.lock"]
    finally:
        holder.kill()
        holder.wait()


def test_sequence_without_events_gets_no_evreal_folder_and_counts_as_done(tmp_path, caplog):
    """An ideal sensor under a steady lamp fires no DVS event; EVREAL cannot load such a folder, so
    none is written, the marker says why, and a rerun does not redo the sequence."""
    config = load_dataset_config(write_config(tmp_path, sequences=1, sensors=["ideal"], emulators=["dvs"],
                                              randomize={"waveforms": ["dc"]}))
    out = tmp_path / "out"
    with caplog.at_level("WARNING", logger="gevsim.experiments.dataset"):
        summary = generate(config, out, cache_dir=tmp_path / "cache")
    assert summary["done"] == 1 and summary["counts"]["events"] == 0
    record = json.loads(marker(out, 0).read_text())
    assert record["evreal"] is None and "EVREAL cannot load a sequence with fewer than 2" in record["evreal_skipped"]
    assert not (out / "evreal" / "seq_00000").exists() and "not written" in caplog.text
    assert finished(config, out, 0) == record
    assert generate(config, out, cache_dir=tmp_path / "cache")["skipped"] == 1


def test_an_edited_preset_file_redoes_the_sequence(tmp_path):
    """Issue 24, item 4: a shard records its preset's contents; editing the preset makes it unfinished."""
    from gevsim.pixel.presets import preset_path

    preset = tmp_path / "my.toml"
    preset.write_text(preset_path("davis346").read_text())
    config = load_dataset_config(write_config(tmp_path, sequences=1, evreal=False, sensors=["my.toml"]))
    out = tmp_path / "out"
    assert generate(config, out, cache_dir=tmp_path / "c")["done"] == 1
    assert finished(config, out, 0) is not None
    preset.write_text(preset.read_text().replace("threshold_on_ln = 0.2 ", "threshold_on_ln = 0.3 "))
    assert finished(config, out, 0) is None
    assert generate(config, out, cache_dir=tmp_path / "c")["done"] == 1


def files_sha256(folder: Path) -> dict[str, str]:
    """{relative path: SHA-256 of its bytes} of every file but what records timings or ownership (markers,
    dataset.json, the mark and the lock): HDF5 shards included, whose layout follows the writes alone (the
    writer flushes each frame and array as it writes it; a handle held past a write by Dask's profiler once
    reordered the frames' chunks: tests/io/test_hdf5.py)."""
    timed = {MARK, LOCK_NAME, "dataset.json"}
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name not in timed and not (p.parent.name == "shards" and p.suffix == ".json")}


def without_seconds(record: dict) -> dict:
    return {k: v for k, v in record.items() if k != "seconds"}


def test_parts_one_after_the_other_reproduce_a_single_run_bit_for_bit(reference, tmp_path):
    """Issue 37, item 6: `dataset --part 0/2` then `--part 1/2` (an array job) give the single run's shards and
    EVREAL files byte for byte; the last part merges them into OUT
    and writes a complete dataset.json."""
    config, ref, cache, _ = reference
    out = tmp_path / "out"
    first = generate_part(config, out, Part(0, 2), cache_dir=cache)
    assert (first["done"], first["merge"], first["unfinished"]) == (2, "waiting", 1)
    assert not out.exists() and sorted(p.name for p in (tmp_path / "out.parts" / "0-of-2" / "shards").glob("*.h5")) \
        == ["seq_00000.h5", "seq_00002.h5"]
    second = generate_part(config, out, Part(1, 2), cache_dir=cache)
    assert (second["done"], second["merge"], second["unfinished"]) == (1, "complete", 0)
    assert not parts_root(out).exists()
    expected = files_sha256(ref)
    assert len(expected) == 3 + 7 * 3 and files_sha256(out) == expected  # 3 shards, 3 EVREAL folders of 7 files
    for i in range(N):
        assert without_seconds(json.loads(marker(out, i).read_text())) == \
            without_seconds(json.loads(marker(ref, i).read_text()))
    index = json.loads((out / "dataset.json").read_text())
    assert index["complete"] and [s["index"] for s in index["sequences"]] == list(range(N))
    again = generate(config, out, cache_dir=cache)  # the merged folder is a dataset folder like any other
    assert (again["done"], again["skipped"], again["merged"]) == (0, N, 0)


def test_merge_takes_what_parts_finished_and_the_next_runs_make_only_the_rest(reference, tmp_path, capsys):
    config, ref, cache, _ = reference
    out = tmp_path / "out"
    assert generate_part(config, out, Part(1, 3), cache_dir=cache)["merge"] == "waiting"  # sequence 1 only
    assert main(["dataset", config.source, "--out", str(out), "--merge"]) == 0
    assert f"merged 1 sequences into {out}; dataset.json lists 1 of 3; 2 not finished anywhere" \
        in capsys.readouterr().err
    index = json.loads((out / "dataset.json").read_text())
    assert not index["complete"] and [s["index"] for s in index["sequences"]] == [1]
    assert files_sha256(out) == {k: v for k, v in files_sha256(ref).items() if "00001" in k}
    redo = generate_part(config, out, Part(1, 3), cache_dir=cache)  # OUT holds sequence 1: not made again
    assert (redo["done"], redo["skipped"], redo["merge"], redo["unfinished"]) == (0, 1, "waiting", 2)
    assert generate_part(config, out, Part(2, 3), cache_dir=cache)["unfinished"] == 1  # sequence 2, in its part
    rest = generate(config, out, cache_dir=cache)  # a run without --part merges the parts, then makes the rest
    assert (rest["merged"], rest["done"], rest["skipped"]) == (1, 1, 2) and not parts_root(out).exists()
    assert files_sha256(out) == files_sha256(ref)


@pytest.mark.parametrize("part, text", [
    ("2/2", "--part: I must be below N (parts are numbered 0 to N-1, as sbatch --array=0-1), got '2/2'"),
    ("0/0", "--part: N must be from 1 to 1000000, got '0/0'"),
    ("a/b", "--part: expected I/N, part I of N (0 <= I < N, as $SLURM_ARRAY_TASK_ID/N), got 'a/b'"),
    ("-1/2", "--part: expected I/N"),
])
def test_a_wrong_part_is_one_line_and_exit_2(tmp_path, capsys, part, text):
    out = tmp_path / "out"
    assert main(["dataset", str(write_config(tmp_path)), "--out", str(out), f"--part={part}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"gevsim: error: {text}")
    assert not out.exists() and not parts_root(out).exists()


def recipe(title: str) -> str:
    """The first Python block of docs/cluster.md after the heading ``title``."""
    text = (Path(__file__).parents[2] / "docs" / "cluster.md").read_text()
    section = text[text.index(f"## {title}\n"):]
    return section[section.index("```python\n") + 10:section.index("\n```\n")]


def test_the_local_cluster_recipe_of_the_docs(reference, tmp_path):
    """docs/cluster.md's LocalCluster recipe, run as written (its function; one worker in a thread, to start
    quickly): a Dask scheduler given by address makes the single run's shards, bit for bit."""
    pytest.importorskip("dask.distributed", reason="the dask extra is not installed")
    config, ref, cache, _ = reference
    namespace: dict = {"__name__": "recipe"}
    exec(compile(recipe("Try it on one machine: LocalCluster"), "docs/cluster.md", "exec"), namespace)
    out = tmp_path / "out"
    assert namespace["make_dataset"](config.source, str(out), "--cache", str(cache), "-q", workers=1,
                                     processes=False) == 0
    assert files_sha256(out) == files_sha256(ref)
    assert json.loads((out / "dataset.json").read_text())["complete"]


def test_cli_parts_say_who_merges(reference, tmp_path, capsys):
    """`gevsim dataset --part` as an array task runs it (here on a Dask scheduler in this process, quick to start):
    each part says what it made and whether the output is merged."""
    distributed = pytest.importorskip("dask.distributed", reason="the dask extra is not installed")
    config, ref, cache, _ = reference
    out = tmp_path / "out"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cl:
        run = ["dataset", config.source, "--out", str(out), "--executor", "dask", "--scheduler", cl.scheduler_address,
               "--cache", str(cache), "-q"]
        assert main([*run, "--part", "1/2"]) == 0
        err = capsys.readouterr().err.splitlines()
        assert err[-2].startswith(f"gevsim: part 1/2: 1 sequences: 1 made, 0 already done; wrote {out}.parts/1-of-2")
        assert err[-1] == "gevsim: 2 sequences not finished yet: the part that finishes last merges every part into " \
            f"{out}"
        assert main([*run, "--part", "0/2"]) == 0
        assert capsys.readouterr().err.splitlines()[-1] == f"gevsim: every part has finished: merged into {out}"
    assert files_sha256(out) == files_sha256(ref) and not parts_root(out).exists()
