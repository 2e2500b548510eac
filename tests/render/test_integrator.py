"""The one-pass light-group integrator: same expectation as Mitsuba's path tracer, group by group."""

import numpy as np
import pytest
from conftest import fast_variant, small, use_variant

from gevsim.optics import luminance
from gevsim.render import MitsubaScene
from gevsim.render.integrator import group_emitters, render_groups

SEEDS = 6
SPP = 64


def seeded_means(render, seeds):
    """Per-pixel mean and standard error over independent renders."""
    stack = np.array([luminance(render(seed)) for seed in seeds], np.float64)
    return stack.mean(axis=0), stack.std(axis=0, ddof=1) / np.sqrt(len(seeds))


@pytest.fixture(scope="module")
def office_scene():
    variant = fast_variant()
    sc = MitsubaScene(small("office"), variant=variant)
    assert sc.one_pass, f"{variant.variant} is a JIT variant: it renders all groups in one pass"
    sc.set_pose(sc.pose_at(0.0))
    return sc


@pytest.fixture
def office(office_scene):
    use_variant(office_scene.variant.variant)  # a test in between may have switched variants
    return office_scene


@pytest.mark.slow
def test_group_images_sum_to_the_path_tracer_within_monte_carlo_error(office):
    groups = group_emitters(office.scene, [office.group(n).emitters for n in office.manifest.group_names])
    ours, ours_se = seeded_means(lambda s: render_groups(office.scene, groups, spp=SPP, seed=s, max_depth=4).sum(0),
                                 range(SEEDS))
    office.set_groups(None)
    ref, ref_se = seeded_means(lambda s: office.render(spp=SPP, seed=100 + s), range(SEEDS))
    se = np.sqrt(ours_se**2 + ref_se**2)
    # Image means: every pixel's error is independent, so the mean's error is tiny.
    assert ours.mean() == pytest.approx(ref.mean(), rel=5 * np.sqrt((se**2).sum()) / se.size / ref.mean() + 1e-4)
    z = np.abs(ours - ref) / np.maximum(se, 1e-12)
    assert np.mean(z > 4) < 0.01  # a 4-sigma excursion is rare for honest estimates


@pytest.mark.slow
@pytest.mark.parametrize("depth", [2, 4])
def test_each_group_is_that_group_rendered_alone_in_expectation(office, depth):
    names = office.manifest.group_names
    groups = group_emitters(office.scene, [office.group(n).emitters for n in names])
    stack = np.array([luminance(render_groups(office.scene, groups, spp=SPP, seed=s, max_depth=depth))
                      for s in range(SEEDS)])
    from mitsuba import load_dict, render

    integrator = load_dict({"type": "path", "max_depth": depth})
    for k, name in enumerate(names):
        office.set_groups({name})
        alone = np.array([luminance(np.array(render(office.scene, integrator=integrator, spp=SPP, seed=50 + s)))
                          for s in range(SEEDS)])
        a, b = stack[:, k].mean(axis=(1, 2)), alone.mean(axis=(1, 2))  # image means per seed
        diff, se = a.mean() - b.mean(), np.sqrt(a.var(ddof=1) / SEEDS + b.var(ddof=1) / SEEDS)
        assert abs(diff) <= 4 * se + 1e-6 * b.mean(), (name, a.mean(), b.mean(), se)
        assert a.mean() > 0
    office.set_groups(None)


def test_one_pass_is_reproducible_and_seeds_are_independent(office):
    groups = group_emitters(office.scene, [office.group(n).emitters for n in office.manifest.group_names])
    a = render_groups(office.scene, groups, spp=4, seed=3, max_depth=4)
    b = render_groups(office.scene, groups, spp=4, seed=3, max_depth=4)
    c = render_groups(office.scene, groups, spp=4, seed=4, max_depth=4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.shape == (2, 48, 64, 3) and a.dtype == np.float32


def test_render_groups_uses_one_pass_or_falls_back_per_group(variants_rgb):
    """Both paths give K images of the same shape; the scalar fallback renders them one by one."""
    sc = MitsubaScene(small("office"), variant=variants_rgb)
    assert sc.one_pass == (not variants_rgb.variant.startswith("scalar"))
    imgs = sc.render_groups(spp=4, seed=1)
    assert imgs.shape == (2, 48, 64, 3) and (imgs.sum(axis=(1, 2, 3)) > 0).all()


def test_subset_renders_are_padded_to_a_short_ladder_of_sizes():
    """Dr.Jit compiles a kernel per path count: subset sizes are padded to round(2^(j/2)), so 1..100000
    pixels need at most 34 kernels per sample count, never more than 42 % extra pixels."""
    from gevsim.render.integrator import padded_count

    sizes = [padded_count(n) for n in range(1, 100_001)]
    assert all(s >= n for n, s in zip(range(1, 100_001), sizes))
    assert max(s / n for n, s in zip(range(1, 100_001), sizes)) <= 1.42
    assert len(set(sizes)) <= 34
