"""Scene-builder helpers: orientation of rectangles and of textures."""

import mitsuba as mi
import numpy as np
import pytest

from gevsim.render import shapes as s


def _render_card(bsdf, variant):
    mi.set_variant(variant.variant)
    t = mi.ScalarTransform4f()
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": t.look_at(origin=[0, 0, 3], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 32, "height": 32, "rfilter": {"type": "box"}}},
        "card": s.rectangle([0, 0, 0], [1, 1], facing="+z", bsdf=bsdf),
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [1, 1, 1]}},
    })
    return np.array(mi.render(scene, spp=16, seed=0))


def test_photographs_hang_upright(variant):
    img = np.zeros((64, 64, 3), np.float32)
    img[:16, :, 0] = 1.0  # red band along the image's top
    img[:, :16, 1] = 1.0  # green band along its left side
    out = _render_card(s.diffuse(img), variant)
    assert out[10, :, 0].mean() > out[21, :, 0].mean() + 0.3  # red at the top of the card
    assert out[:, 11, 1].mean() > out[:, 21, 1].mean() + 0.3  # green at its left


@pytest.mark.parametrize("facing, normal", [("+x", [1, 0, 0]), ("-x", [-1, 0, 0]), ("+y", [0, 1, 0]),
                                            ("-y", [0, -1, 0]), ("+z", [0, 0, 1]), ("-z", [0, 0, -1])])
def test_rectangle_faces_where_asked(facing, normal):
    m = np.array(s.rectangle([1, 2, 3], [2, 4], facing=facing)["to_world"].matrix, float).reshape(4, 4)
    n = m[:3, 2] / np.linalg.norm(m[:3, 2])
    np.testing.assert_allclose(n, normal, atol=1e-6)
    np.testing.assert_allclose(m[:3, 3], [1, 2, 3])
    assert 4 * np.linalg.norm(np.cross(m[:3, 0], m[:3, 1])) == pytest.approx(8.0)


def test_unknown_texture_and_facing_are_errors():
    with pytest.raises(ValueError, match="astronot"):
        s.photo("astronot")
    with pytest.raises(ValueError, match="'up'"):
        s.rectangle([0, 0, 0], [1, 1], facing="up")
