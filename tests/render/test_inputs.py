"""The files a scene is made of: found, hashed, and in the render cache key (an edited texture re-renders)."""

import importlib
import sys

import numpy as np
from conftest import textured_scene

from gevsim.render import MitsubaScene, load, override, render_basis
from gevsim.render.inputs import build_shapes, scene_digest, scene_input_files


def names(files):
    return sorted(f.name for f in files)


def lamp_scene(folder, module):
    """A manifest beside ``textured.toml`` whose builder b.py takes its lamp's SIZE from ``module``."""
    (folder / "b.py").write_text(
        f"from {module} import SIZE\n\nfrom gevsim.render import shapes as s\n\n\ndef build(options):\n"
        "    return {'lamp': s.rectangle([0, 0, 4.5], [SIZE, SIZE], facing='-z', emitter=s.area_light())}\n")
    manifest = folder / "b.toml"
    manifest.write_text((folder / "textured.toml").read_text().replace('"textured.py"', '"b.py"'))
    return manifest


def test_manifests_builder_and_every_loaded_file_are_listed(tmp_path, variant):
    manifest = textured_scene(tmp_path)
    assert names(scene_input_files(load(manifest))) == ["backdrop.exr", "card_texture.npy", "textured.py",
                                                        "textured.toml"]
    child = tmp_path / "child.toml"
    child.write_text('[scene]\nextends = "textured.toml"\nname = "child"\n')
    files = scene_input_files(load(child))
    assert files[:2] == (child.resolve(), manifest.resolve())  # the manifests first, in extends order
    assert names(files) == ["backdrop.exr", "card_texture.npy", "child.toml", "textured.py", "textured.toml"]


def test_files_mitsuba_opens_itself_helper_modules_and_option_files_are_found(tmp_path, variant):
    textured_scene(tmp_path)
    (tmp_path / "grain.exr").write_bytes(b"not read by this test")
    (tmp_path / "helper.py").write_text("SIZE = 2.0\n")
    (tmp_path / "extra.npy").write_bytes(b"named in the options")
    (tmp_path / "unrelated.txt").write_text("never referenced")
    (tmp_path / "b.py").write_text(
        "import runpy\nfrom pathlib import Path\n\nfrom gevsim.render import shapes as s\n\n"
        "HERE = Path(__file__).parent\nGRAIN = 'grain.exr'  # what mi.Bitmap(HERE / GRAIN) would open in C++\n\n"
        "def build(options):\n"
        "    size = runpy.run_path(str(HERE / 'helper.py'))['SIZE']\n"
        "    return {'lamp': s.rectangle([0, 0, 4.5], [size, size], facing='-z', emitter=s.area_light())}\n")
    manifest = tmp_path / "b.toml"
    manifest.write_text((tmp_path / "textured.toml").read_text()
                        .replace('builder = "textured.py"', 'builder = "b.py"\noptions = { extra = "extra.npy" }'))
    assert names(scene_input_files(load(manifest))) == ["b.py", "b.toml", "extra.npy", "grain.exr", "helper.py"]


def test_from_helper_import_is_found_in_every_build_of_a_process(tmp_path, variant, monkeypatch):
    """Issue 24 #7: a second build in one process (the study's prerender) missed ``from helper import X``,
    so the scene's digest changed within the process. Here the helper is even imported before the first build."""
    textured_scene(tmp_path)
    helper = f"helper_{tmp_path.name}"  # a module name no other test imports
    (tmp_path / f"{helper}.py").write_text(f"from {helper}_b import SIZE  # a helper's own helper\n")
    (tmp_path / f"{helper}_b.py").write_text("SIZE = 2.0\n")
    manifest = lamp_scene(tmp_path, helper)
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in (helper, f"{helper}_b"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    importlib.import_module(helper)
    first = scene_digest(manifest)
    _, files = build_shapes(load(manifest))  # the second build in this process
    assert names(files) == ["b.py", f"{helper}.py", f"{helper}_b.py"]
    assert scene_digest(manifest) == first
    (tmp_path / f"{helper}_b.py").write_text("SIZE = 3.0\n")
    assert scene_digest(manifest) != first


def test_digest_follows_the_contents_of_every_input(tmp_path, variant):
    manifest = textured_scene(tmp_path)
    first = scene_digest(manifest)
    textured_scene(tmp_path)  # the same contents written again
    assert scene_digest(manifest) == first
    textured_scene(tmp_path, backdrop=0.6)
    second = scene_digest(manifest)
    assert second != first
    manifest.write_text(manifest.read_text().replace("luminance_cd_m2 = 1e5", "luminance_cd_m2 = 1e3"))
    assert scene_digest(manifest) not in (first, second)


def test_an_edited_texture_is_rendered_again(tmp_path, variant):
    manifest = textured_scene(tmp_path / "scene")
    cache = tmp_path / "cache"

    def render():
        scene = MitsubaScene(override(load(manifest), width=24, height=18, spp=2), variant=variant)
        return render_basis(scene, cache_dir=cache)

    first = render()
    assert (first.render_s > 0).all() and (render().render_s == 0).all()  # the second from the cache
    for edit in ({"backdrop": 0.9}, {"card": 0.1}):  # loaded by Mitsuba from a filename; by numpy in the builder
        textured_scene(tmp_path / "scene", **edit)
        again = render()
        assert (again.render_s > 0).all(), f"{edit}: served from the cache"
        assert not np.array_equal(again.images, first.images)


def test_a_library_on_pythonpath_is_not_a_scene_input(tmp_path, variant, monkeypatch):
    """Issue 26: with packages outside the interpreter's prefix (PYTHONPATH, .pth files) a builder's library
    opened its files on first import only, so the scene digest (and a study's run ids) changed between a
    process's first and second build. A folder on sys.path other than the scene's holds libraries."""
    textured_scene(tmp_path / "scene")
    lib = tmp_path / "lib"
    lib.mkdir()
    name = f"fancylib_{tmp_path.name}"
    (lib / "table.txt").write_text("2.0")
    (lib / f"{name}.py").write_text("from pathlib import Path\n\n"
                                    "SIZE = float((Path(__file__).parent / 'table.txt').read_text())\n")
    manifest = lamp_scene(tmp_path / "scene", name)
    monkeypatch.syspath_prepend(str(lib))
    monkeypatch.delitem(sys.modules, name, raising=False)
    first = scene_digest(manifest)  # the first build imports the library (it opens table.txt)
    _, files = build_shapes(load(manifest))
    assert names(files) == ["b.py"]
    assert scene_digest(manifest) == first
