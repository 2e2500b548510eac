"""Users' own Mitsuba XML scenes: emission from the manifest, includes and textures in the cache key."""

import os
import threading

import numpy as np
import pytest
from conftest import small

from gevsim.cli import main
from gevsim.errors import ConfigError
from gevsim.optics import luminance
from gevsim.render import MitsubaScene, input_files, load
from gevsim.render.basis import cache_key
from gevsim.render.inputs import file_sha256, scene_digest
from gevsim.render.xml_scene import xml_inputs

SCENE_XML = """<scene version="3.0.0">
    <default name="floor_grey" value="0.5"/>
    <include filename="parts/lamp.xml"/>
    <shape type="rectangle" id="panel">
        <transform name="to_world"><scale x="4" y="3" z="1"/><translate x="0" y="1" z="-2"/></transform>
        <emitter type="area"><rgb name="radiance" value="1.0"/></emitter>
    </shape>
    <shape type="rectangle" id="floor">
        <transform name="to_world">
            <scale x="5" y="5" z="1"/><rotate x="1" angle="-90"/><translate x="0" y="-1" z="0"/>
        </transform>
        <bsdf type="diffuse">
            <texture type="bitmap" name="reflectance"><string name="filename" value="textures/floor.png"/></texture>
        </bsdf>
    </shape>
</scene>
"""
LAMP_XML = """<scene version="3.0.0">
    <shape type="sphere" id="lamp">
        <point name="center" x="1.0" y="0.0" z="0.0"/><float name="radius" value="0.2"/>
        <emitter type="area"><rgb name="radiance" value="1.0"/></emitter>
    </shape>
</scene>
"""
MANIFEST = """[scene]
name = "xml_panel"
builder = "scene.xml"

[render]
width = 64
height = 48
spp = 4
seed = 7

[sequence]
duration_s = 0.01

[camera]
fov_deg = 40.0
keyframes = [{ t_s = 0.0, origin = [0.0, 0.5, 3.0], target = [0.0, 0.5, -2.0] }]

[light_groups.panel]
emitters = ["panel"]
spectrum = "D65"
luminance_cd_m2 = 1000.0
waveform = { type = "pwm", frequency_hz = 1000.0, duty = 0.25 }

[light_groups.lamp]
emitters = ["lamp"]
radiance_w_m2_sr = [3.0, 2.0, 1.0]
waveform = { type = "dc" }
"""


@pytest.fixture
def xml_scene(tmp_path, variant):
    import mitsuba as mi

    (tmp_path / "parts").mkdir()
    (tmp_path / "textures").mkdir()
    (tmp_path / "scene.xml").write_text(SCENE_XML)
    (tmp_path / "parts" / "lamp.xml").write_text(LAMP_XML)
    checker = np.kron(np.indices((4, 4)).sum(0) % 2, np.ones((8, 8)))[..., None].repeat(3, -1) * 0.6 + 0.2
    mi.Bitmap(checker.astype(np.float32)).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, True).write(
        str(tmp_path / "textures" / "floor.png"))
    (tmp_path / "scene.toml").write_text(MANIFEST)
    return tmp_path / "scene.toml"


def test_xml_emitters_get_the_manifest_luminance_and_the_texture_is_used(xml_scene, variant):
    sc = MitsubaScene(load(xml_scene), variant=variant)
    sc.set_pose(sc.pose_at(0.0))
    sc.set_groups({"panel"})
    panel = luminance(sc.render()[..., :3])
    np.testing.assert_allclose(683.0 * panel[:8], 1000.0, rtol=1e-4)  # top rows see only the panel
    sc.set_groups({"lamp"})
    lamp = sc.render()[..., :3]
    assert lamp.max() == pytest.approx(3.0, rel=1e-4)  # the lamp's stated radiance, seen directly
    sc.set_groups(None)
    floor = luminance(sc.render()[..., :3])[-10:]  # bottom rows: the checkered floor lit by the panel
    assert floor.std() > 0.1 * floor.mean() > 0


def test_every_file_the_xml_reads_is_in_the_cache_key(xml_scene, variant):
    folder = xml_scene.parent
    assert [p.relative_to(folder).as_posix() for p in xml_inputs(folder / "scene.xml")] == [
        "scene.xml", "parts/lamp.xml", "textures/floor.png"]
    def key_now():
        sc = MitsubaScene(small(xml_scene), variant=variant)
        return cache_key(sc, sc.pose_at(0.0))

    key = key_now()
    for name in ("textures/floor.png", "parts/lamp.xml"):
        path = folder / name
        original = path.read_bytes()
        path.write_bytes(original + b" ")
        assert key_now() != key, name
        path.write_bytes(original)
    assert key_now() == key


def test_xml_scene_errors_name_the_file(xml_scene, variant):
    folder = xml_scene.parent
    (folder / "scene.toml").write_text(MANIFEST.split("[light_groups.lamp]")[0])  # the lamp in no group
    with pytest.raises(ConfigError, match="belongs to no light group"):
        MitsubaScene(load(xml_scene), variant=variant)
    (folder / "scene.xml").write_text(SCENE_XML.replace("</scene>", "<shape"))
    (folder / "scene.toml").write_text(MANIFEST)
    with pytest.raises(ConfigError, match="scene.xml"):
        MitsubaScene(load(xml_scene), variant=variant)


def returns_soon(call, *args, timeout_s=20.0):
    """``call(*args)``'s result or exception, or a failure (not a hang) where it blocks, as on a FIFO."""
    done: list = []

    def run():
        try:
            done.append(call(*args))
        except Exception as exc:  # handed to the test
            done.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(timeout_s)
    assert done, f"{call.__name__} still blocked after {timeout_s} s"
    return done[0]


@pytest.mark.parametrize("via", ["default", "options"])
def test_a_texture_named_through_a_parameter_is_in_the_key(xml_scene, variant, via):
    """Issue 24 #3: a ``$name`` filename, set by the XML's ``<default>`` or the manifest's options."""
    folder = xml_scene.parent
    (folder / "scene.xml").write_text(SCENE_XML.replace('value="textures/floor.png"', 'value="$floor_tex"').replace(
        "<include", '<default name="floor_tex" value="textures/floor.png"/>\n    <include'))
    texture = folder / "textures" / "floor.png"
    if via == "options":  # the option wins over the <default>
        texture = texture.with_name("other.png")
        texture.write_bytes((folder / "textures" / "floor.png").read_bytes())
        option = '\noptions = { floor_tex = "textures/other.png" }'
        xml_scene.write_text(MANIFEST.replace('"scene.xml"', '"scene.xml"' + option, 1))
    listed = xml_inputs(folder / "scene.xml", load(xml_scene).options)
    assert [p.relative_to(folder).as_posix() for p in listed] == [
        "scene.xml", "parts/lamp.xml", texture.relative_to(folder).as_posix()]

    def keys():
        sc = MitsubaScene(small(xml_scene), variant=variant)
        return cache_key(sc, sc.pose_at(0.0)), scene_digest(xml_scene)

    before = keys()
    original = texture.read_bytes()
    texture.write_bytes(original + b" ")
    after = keys()
    assert after[0] != before[0] and after[1] != before[1]
    texture.write_bytes(original)
    assert keys() == before


@pytest.mark.parametrize("kind", ["fifo", "device", "folder"])
def test_a_fifo_device_or_folder_as_a_filename_is_refused_without_opening_it(tmp_path, kind):
    """Issue 24 #12: hashing ``/dev/zero`` or a FIFO ran for ever; now one error names the XML and element."""
    target = {"fifo": "tex.png", "device": os.devnull, "folder": "textures"}[kind]
    if kind == "fifo":
        os.mkfifo(tmp_path / target)
    elif kind == "folder":
        (tmp_path / target).mkdir()
    xml = tmp_path / "scene.xml"
    xml.write_text(SCENE_XML.replace('<include filename="parts/lamp.xml"/>', "").replace(
        "textures/floor.png", "$t").replace("<shape", f'<default name="t" value="{target}"/><shape', 1))
    error = returns_soon(xml_inputs, xml)
    assert isinstance(error, ConfigError)
    assert str(error).startswith(f'{xml}: <string name="filename" value="$t">: names ')
    assert {"fifo": "a FIFO", "device": "a device", "folder": "a folder"}[kind] in str(error)
    if kind != "folder":  # the hash itself refuses too, for files found another way
        assert isinstance(returns_soon(file_sha256, tmp_path / target if kind == "fifo" else target), ConfigError)


def test_a_study_on_a_scene_that_names_a_fifo_exits_2_with_one_line(xml_scene, tmp_path, capsys):
    folder = xml_scene.parent
    os.mkfifo(folder / "pipe.png")
    (folder / "scene.xml").write_text(SCENE_XML.replace("textures/floor.png", "pipe.png"))
    study = folder / "study.toml"
    study.write_text('[study]\nscene = "scene.toml"\nemulators = ["dvs", "gradient"]\nflicker_group = "panel"\n'
                     'duration_s = 0.004\nrepeats = 1\n[sweep]\nwaveform = ["pwm"]\n')
    code = returns_soon(main, ["study", str(study), "--out", str(tmp_path / "out"), "--workers", "1", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("gevsim: error: ") and "scene.xml" in err[0] and "pipe.png" in err[0]
    assert "a FIFO, not a regular file" in err[0]


def test_a_file_over_the_size_limit_is_refused_with_its_size_and_the_limit(xml_scene, monkeypatch):
    folder = xml_scene.parent
    texture = folder / "textures" / "floor.png"
    texture.write_bytes(texture.read_bytes() + bytes(4096))  # larger than the XML files
    size = texture.stat().st_size
    monkeypatch.setattr(input_files, "MAX_INPUT_BYTES", size - 1)
    with pytest.raises(ConfigError, match=rf'scene.xml: <string name="filename" value="textures/floor.png">: '
                                          rf".*floor.png of {size} bytes, over the limit of {size - 1} bytes"):
        xml_inputs(folder / "scene.xml")
