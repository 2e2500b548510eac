"""Office: a 5 x 4 x 3 m room with a ceiling LED panel and a daylight window.

Emitters (ids used by the manifest's light groups): ``ceiling_panel``
(600 x 1200 mm LED troffer, the usual office fixture) and ``window``
(a 1.6 x 1.2 m pane on the left wall). Textures: scikit-image's
``astronaut`` photograph as a poster, ``brick`` on a feature wall,
``gravel`` as a carpet.
"""

from gevsim.render import shapes as s


def build(options):
    poster = options.get("poster", "astronaut")
    plaster = s.diffuse([0.7, 0.68, 0.62])
    scene = s.room(5.0, 4.0, 3.0, walls=plaster, floor=s.diffuse(s.photo("gravel", albedo=0.35)),
                   ceiling=s.diffuse([0.8, 0.8, 0.8]))
    scene["wall_back"]["bsdf"] = s.diffuse(s.photo("brick", albedo=0.6))
    scene.update(
        ceiling_panel=s.rectangle([0.0, 2.99, 0.0], [1.2, 0.6], facing="-y", emitter=s.area_light()),
        window=s.rectangle([-2.49, 1.6, -0.5], [1.6, 1.2], facing="+x", emitter=s.area_light()),
        poster=s.rectangle([0.6, 1.6, -1.99], [1.2, 1.2], facing="+z", bsdf=s.diffuse(s.photo(poster))),
        desk_top=s.box([0.0, 0.74, -1.2], [1.6, 0.04, 0.8], bsdf=s.diffuse([0.45, 0.3, 0.18])),
        desk_leg_l=s.box([-0.75, 0.36, -1.2], [0.05, 0.72, 0.7], bsdf=s.diffuse([0.2, 0.2, 0.2])),
        desk_leg_r=s.box([0.75, 0.36, -1.2], [0.05, 0.72, 0.7], bsdf=s.diffuse([0.2, 0.2, 0.2])),
        monitor=s.rectangle([0.0, 1.05, -1.45], [0.6, 0.36], facing="+z", bsdf=s.diffuse(s.photo("camera", albedo=0.5))),
        mug=s.cylinder([0.5, 0.76, -1.0], [0.5, 0.86, -1.0], 0.04, bsdf=s.diffuse([0.8, 0.1, 0.1])),
        cabinet=s.box([-1.8, 0.6, -1.6], [0.8, 1.2, 0.6], bsdf=s.diffuse(s.photo("coffee", albedo=0.6))),
    )
    return scene
