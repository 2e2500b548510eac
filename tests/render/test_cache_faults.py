"""A damaged or unusable render cache costs a render and a warning, never the run."""

import logging
import os
from pathlib import Path

import numpy as np
import pytest

from gevsim.io import read_exr_layers, write_exr_layers
from gevsim.render import MitsubaScene, load, override, render_basis

CARD = Path(__file__).parents[1] / "data" / "card.toml"


@pytest.fixture(autouse=True)
def _render_log_at_warning(caplog):
    """These tests count warnings: the render's INFO lines stay out whatever earlier tests left set."""
    caplog.set_level(logging.WARNING, logger="gevsim.render")


@pytest.fixture
def scene(variant):
    return MitsubaScene(override(load(CARD), width=24, height=18, spp=2), variant=variant)


def truncate(path):
    path.write_bytes(path.read_bytes()[:2000])


def garbage(path):
    path.write_text("not an EXR file")


def foreign_metadata(path):  # an EXR that reads, but whose record is not what gevsim writes
    layers, meta = read_exr_layers(path)
    write_exr_layers(path, layers, metadata={**meta, "report": {"spp": 2}})


def nan_pixels(path):
    layers, meta = read_exr_layers(path)
    layers["group0"][3, 4] = np.nan
    write_exr_layers(path, layers, metadata=meta)


def other_size(path):
    layers, meta = read_exr_layers(path)
    write_exr_layers(path, {k: v[:-2] for k, v in layers.items()}, metadata=meta)


@pytest.mark.parametrize("damage", [truncate, garbage, foreign_metadata, nan_pixels, other_size])
def test_a_damaged_cache_file_is_rendered_again_with_a_warning(tmp_path, scene, caplog, damage):
    first = render_basis(scene, cache_dir=tmp_path)
    (path,) = tmp_path.glob("*.exr")
    damage(path)
    with caplog.at_level(logging.WARNING, logger="gevsim.render"):
        again = render_basis(scene, cache_dir=tmp_path)
    assert (again.render_s > 0).all()
    assert any(str(path) in r.getMessage() and "rendering again" in r.getMessage() for r in caplog.records)
    np.testing.assert_allclose(again.images, first.images, rtol=1e-6)
    caplog.clear()
    third = render_basis(scene, cache_dir=tmp_path)  # the file was replaced by the new render
    assert (third.render_s == 0).all() and not caplog.records


def test_a_cache_folder_that_cannot_be_made_is_skipped_with_a_warning(tmp_path, scene, caplog):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder's parent should be")
    with caplog.at_level(logging.WARNING, logger="gevsim.render"):
        basis = render_basis(scene, cache_dir=blocker / "cache")
    assert (basis.render_s > 0).all()
    assert [r.getMessage() for r in caplog.records if "without caching" in r.getMessage()] == [
        next(r.getMessage() for r in caplog.records if str(blocker / "cache") in r.getMessage())]


def test_a_read_only_cache_is_read_and_the_run_goes_on_without_writing(tmp_path, scene, caplog, monkeypatch):
    cache = tmp_path / "cache"
    first = render_basis(scene, cache_dir=cache)
    cache.chmod(0o555)
    try:
        if os.geteuid() == 0:  # root writes anywhere: make the write fail as it would for a user
            def refuse(*args, **kwargs):
                raise PermissionError(13, "Permission denied", str(cache))

            monkeypatch.setattr("gevsim.io.staging.tempfile.mkstemp", refuse)
        assert (render_basis(scene, cache_dir=cache).render_s == 0).all()  # hits are still read
        for f in cache.glob("*.exr"):
            os.chmod(cache, 0o755)
            f.unlink()
            os.chmod(cache, 0o555)
        with caplog.at_level(logging.WARNING, logger="gevsim.render"):
            again = render_basis(scene, cache_dir=cache)
    finally:
        cache.chmod(0o755)
    assert (again.render_s > 0).all()
    np.testing.assert_allclose(again.images, first.images, rtol=1e-6)
    warnings = [r.getMessage() for r in caplog.records]
    assert len(warnings) == 1 and str(cache) in warnings[0] and "without caching" in warnings[0]
    assert list(cache.iterdir()) == []
