"""Test scene: a large emitting panel facing the camera, a grey floor below it,
and a small lamp at the side. Used for radiometric and linearity tests."""

from gevsim.render import shapes as s


def build(options):
    return {
        "panel": s.rectangle([0.0, 1.0, -2.0], [8.0, 6.0], facing="+z", emitter=s.area_light()),
        "floor": s.rectangle([0.0, -1.0, 0.0], [10.0, 10.0], facing="+y", bsdf=s.diffuse([0.5, 0.5, 0.5])),
        "lamp": s.sphere([1.0, 0.0, 0.0], 0.2, emitter=s.area_light()),
        "cube": s.box([-0.6, -0.7, -0.5], [0.5, 0.5, 0.5], bsdf=s.diffuse([0.6, 0.3, 0.2])),
    }
