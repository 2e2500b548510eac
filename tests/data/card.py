"""Test scene: a photograph on a card lit by a single (flickering) lamp."""

from gevsim.render import shapes as s


def build(options):
    return {
        "card": s.rectangle([0.0, 0.0, 0.0], [2.0, 1.5], facing="+z", bsdf=s.diffuse(s.photo("camera"))),
        "lamp": s.rectangle([0.0, 0.0, 4.5], [2.0, 2.0], facing="-z", emitter=s.area_light()),
    }
