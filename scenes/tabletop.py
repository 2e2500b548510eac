"""Tabletop: textured objects under a magnetic-ballast fluorescent tube.

Emitters: ``tube`` (a T8 tube, 1.2 m long, 13 mm radius, 1 m above the
table) and ``desk_lamp`` (a small incandescent shade to the side). The
sphere ``ball`` rolls across the table (moved by the manifest). Textures:
scikit-image's ``coffee``, ``chelsea``, ``rocket`` and ``moon`` photographs.
"""

from gevsim.render import shapes as s


def build(options):
    return {
        "table": s.rectangle([0.0, 0.0, 0.4], [2.4, 2.0], facing="+y", bsdf=s.diffuse(s.photo("moon", albedo=0.5))),
        "backdrop": s.rectangle([0.0, 0.6, -0.6], [2.0, 1.2], facing="+z", bsdf=s.diffuse(s.photo("rocket", albedo=0.6))),
        "floor": s.rectangle([0.0, -0.75, 0.0], [6.0, 6.0], facing="+y", bsdf=s.diffuse([0.2, 0.2, 0.2])),
        "book": s.box([-0.45, 0.03, 0.05], [0.3, 0.06, 0.22], bsdf=s.diffuse(s.photo("coffee", albedo=0.7))),
        "photo_frame": s.rectangle([0.35, 0.15, -0.3], [0.36, 0.27], facing="+z", bsdf=s.diffuse(s.photo("chelsea"))),
        "can": s.cylinder([0.1, 0.0, -0.15], [0.1, 0.12, -0.15], 0.033, bsdf=s.diffuse([0.1, 0.3, 0.7])),
        "ball": s.sphere([-0.2, 0.05, 0.2], 0.05, bsdf=s.diffuse([0.8, 0.6, 0.1])),
        "tube": s.cylinder([-0.6, 1.0, -0.1], [0.6, 1.0, -0.1], 0.013, emitter=s.area_light()),
        "desk_lamp": s.sphere([0.8, 0.45, 0.1], 0.06, emitter=s.area_light()),
    }
