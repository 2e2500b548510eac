"""Street at night: a high-pressure sodium lamp over a road, a car driving past.

Emitters: ``sodium_lamp`` (luminaire bowl 0.6 x 0.3 m at 6 m height) and the
car's ``headlight_left`` / ``headlight_right``. The car is ``car_body``,
``car_cabin`` and the two headlights, moved together by the manifest.
Textures: generated asphalt noise, scikit-image's ``brick`` on the houses.
"""

from gevsim.render import shapes as s


def build(options):
    asphalt = s.diffuse(s.noise_texture((256, 256), mean=0.08, spread=0.04, seed=3))
    brick = s.diffuse(s.photo("brick", albedo=0.5))
    x0 = float(options.get("car_start_x_m", 0.0))
    return {
        "road": s.rectangle([0.0, 0.0, -2.0], [40.0, 20.0], facing="+y", bsdf=asphalt),
        "kerb": s.box([0.0, 0.07, -3.6], [40.0, 0.15, 0.3], bsdf=s.diffuse([0.35, 0.35, 0.33])),
        "house_a": s.box([-5.0, 3.0, -9.0], [7.0, 6.0, 4.0], bsdf=brick),
        "house_b": s.box([4.5, 4.0, -10.0], [6.0, 8.0, 4.0], bsdf=brick),
        "door": s.rectangle([-4.0, 1.05, -6.99], [1.0, 2.1], facing="+z", bsdf=s.diffuse(s.photo("grass", albedo=0.3))),
        "pole": s.cylinder([-2.0, 0.0, -4.0], [-2.0, 6.2, -4.0], 0.08, bsdf=s.diffuse([0.3, 0.3, 0.3])),
        "arm": s.box([-1.3, 6.2, -4.0], [1.4, 0.08, 0.08], bsdf=s.diffuse([0.3, 0.3, 0.3])),
        "sodium_lamp": s.rectangle([-0.8, 6.1, -4.0], [0.6, 0.3], facing="-y", emitter=s.area_light()),
        "car_body": s.box([x0, 0.55, -1.5], [4.2, 0.7, 1.8], bsdf=s.diffuse([0.5, 0.05, 0.05])),
        "car_cabin": s.box([x0 - 0.3, 1.15, -1.5], [2.2, 0.55, 1.6], bsdf=s.diffuse([0.1, 0.1, 0.12])),
        "headlight_left": s.rectangle([x0 + 2.11, 0.6, -0.9], [0.3, 0.12], facing="+x", emitter=s.area_light()),
        "headlight_right": s.rectangle([x0 + 2.11, 0.6, -2.1], [0.3, 0.12], facing="+x", emitter=s.area_light()),
    }
