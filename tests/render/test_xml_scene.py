"""Users' own Mitsuba XML scenes: emission from the manifest, includes and textures in the cache key."""

import numpy as np
import pytest
from conftest import small

from gevsim.errors import ConfigError
from gevsim.optics import luminance
from gevsim.render import MitsubaScene, load
from gevsim.render.basis import cache_key
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
