"""Render to a noise target: the batch error estimator, the stop rule, settings and the cache."""

import time
from types import SimpleNamespace

import numpy as np
import pytest

from gevsim.errors import ConfigError
from gevsim.render import load, override
from gevsim.render.basis import quality_request, render_pose, serves
from gevsim.render.convergence import BatchAccumulator, mixture_weights, needed_spp


def test_mixture_weights_are_the_corners_of_the_waveform_ranges():
    w = mixture_weights([(0.0, 10.0 / 3.0), (1.0, 1.0)])  # PWM duty 0.3 and a DC lamp
    np.testing.assert_allclose(w, [[0.0, 1.0], [10.0 / 3.0, 1.0]])
    assert mixture_weights([(0.5, 2.0), (0.0, 3.0), (1.0, 1.0)]).shape == (4, 3)
    with pytest.raises(ValueError, match="0 <= min <= max"):
        mixture_weights([(2.0, 1.0)])


def synthetic_batch(rng, mu, sigma, spp, shared=False):
    """K group images (K, H, W, 1): mean mu[k], per-sample std sigma[k], averaged over spp samples."""
    k = len(mu)
    shape = (40, 50)
    eps = rng.standard_normal((1 if shared else k,) + shape)
    eps = np.broadcast_to(eps, (k,) + shape)
    img = np.array(mu)[:, None, None] + np.array(sigma)[:, None, None] * eps / np.sqrt(spp)
    return img[..., None], img


@pytest.mark.parametrize("sizes", [[16] * 40, [8, 8, 16, 16, 32, 32] * 6])
def test_absolute_error_matches_the_known_variance(rng, sizes):
    """Independent group noise: SE(ln Y(w)) = sqrt(sum w_k^2 s_k^2 / N) / sum w_k mu_k."""
    mu, sigma = [2.0, 5.0], [3.0, 4.0]
    mixtures = np.array([[0.0, 1.0], [3.0, 1.0]])
    acc = BatchAccumulator(mixtures, floor_rel=1e-9, metric="absolute")
    for n in sizes:
        images, lum = synthetic_batch(rng, mu, sigma, n)
        acc.add(images, lum, n)
    n_total = sum(sizes)
    expected = max(np.sqrt((w**2 * np.square(sigma)).sum() / n_total) / (w @ mu) for w in mixtures)
    se = acc.se_ln()
    assert se.shape == (40, 50)
    # Each pixel's estimate has B - 1 degrees of freedom: its median is close, its spread ~ 1/sqrt(2(B-1)).
    assert np.median(se) == pytest.approx(expected, rel=0.05)
    np.testing.assert_allclose(acc.mean()[..., 0].mean(axis=(1, 2)), mu, rtol=0.01)


def test_flicker_metric_ignores_noise_shared_by_every_mixture(rng):
    """When every group's relative error is the same sample (shared paths, shared texture), the
    mixture's ln changes with w carry no noise; the absolute error of ln Y does."""
    mu = [2.0, 5.0]
    sigma = [0.2 * 2.0, 0.2 * 5.0]
    mixtures = np.array([[0.0, 1.0], [3.0, 1.0]])
    flick = BatchAccumulator(mixtures, metric="flicker")
    absolute = BatchAccumulator(mixtures, metric="absolute")
    for _ in range(20):
        images, lum = synthetic_batch(rng, mu, sigma, 16, shared=True)
        flick.add(images, lum, 16)
        absolute.add(images, lum, 16)
    assert np.median(absolute.se_ln()) == pytest.approx(0.2 / np.sqrt(320), rel=0.1)
    assert flick.se_ln().max() < 1e-6


def test_half_difference_has_the_variance_of_the_estimate_error(rng):
    mu, sigma = [1.0], [2.0]
    acc = BatchAccumulator(np.array([[1.0]]))
    for _ in range(32):
        images, lum = synthetic_batch(rng, mu, sigma, 8)
        acc.add(images, lum, 8)
    err = acc.mean() - 1.0
    assert acc.noise().std() == pytest.approx(2.0 / np.sqrt(256), rel=0.05)
    assert err.std() == pytest.approx(2.0 / np.sqrt(256), rel=0.05)
    # The noise sample is independent of the estimate's own error.
    assert abs(np.corrcoef(acc.noise().ravel(), err.ravel())[0, 1]) < 0.05


class FakeScene:
    """A 'renderer' whose groups have known per-sample noise (for the stop rule)."""

    def __init__(self, sigma=2.0, delay_s=0.0, **render):
        defaults = {"sampler": "independent"} if "spp" in render else {"sampler": "independent", "max_spp": 65536}
        settings = override(load("office"), width=20, height=10, **{**defaults, **render}).render
        self.manifest = SimpleNamespace(render=settings)
        self.sigma, self.delay_s = sigma, delay_s
        self.rng = np.random.default_rng(7)
        self.one_pass_seen = set()

    def sample_count(self, spp):
        return spp

    one_pass = True

    def render_groups(self, *, spp, seed, one_pass=None, grid=None, pixels=None):
        self.one_pass_seen.add(one_pass)
        time.sleep(self.delay_s)
        mu = np.array([1.0, 3.0])[:, None, None, None]
        sigma = np.broadcast_to(np.asarray(self.sigma, float), (10, 20))[None, ..., None]
        noise = self.rng.standard_normal((2, 10, 20, 1)) * sigma / np.sqrt(spp)
        images = np.repeat(mu + noise, 3, axis=-1).astype(np.float32)
        return images if pixels is None else images.reshape(2, 1, -1, 3)[:, :, pixels]


def test_stop_rule_stops_near_the_predicted_sample_count():
    scene = FakeScene(noise_target_ln=0.02, noise_metric="absolute")
    mixtures = mixture_weights([(0.0, 2.0), (1.0, 1.0)])
    request = quality_request(scene.manifest.render, mixtures, 0.02)
    _, _, se_map, report = render_pose(scene, request)
    # Worst mixture (2, 1): mean 5, per-sample std 2 * sqrt(5): SE = 4.47 / sqrt(N) / 5 <= 0.02 -> N >= 2000.
    predicted = (2.0 * np.sqrt(5.0) / 5.0 / 0.02) ** 2
    assert report.stopped_by == "target" and report.reached
    assert report.se_ln <= 0.02 and float(np.percentile(se_map, 99)) == pytest.approx(report.se_ln)
    assert predicted <= report.spp <= 2.5 * predicted
    assert needed_spp(report.spp, report.se_ln, 0.02) <= report.spp


def test_adaptive_sampling_meets_the_same_stop_rule_with_fewer_samples():
    """Per-pixel adaptive sampling: pixels with a quarter of the noise stop once under half the target,
    the noisy ones go on to it; same stop rule (p99 <= target), fewer samples, the same unbiased mean."""
    sigma = np.where(np.arange(20) < 10, 0.5, 2.0)[None, :].repeat(10, axis=0)
    out = {}
    for sampling in ("uniform", "adaptive"):
        scene = FakeScene(sigma=sigma, noise_target_ln=0.02, noise_metric="absolute", sampling=sampling)
        request = quality_request(scene.manifest.render, mixture_weights([(0.0, 2.0), (1.0, 1.0)]), 0.02)
        assert request["sampling"] == sampling
        mean, _, se_map, report = render_pose(scene, request)
        assert report.stopped_by == "target" and float(np.percentile(se_map, 99)) <= 0.02
        out[sampling] = mean, se_map
    mean, se_map = out["adaptive"]
    # Quiet pixels: about (0.5 / 2)^2 = 1/16 of the noisy ones' samples would reach the same error; they
    # stop under 0.01 instead of 0.02 (4x fewer), so they carry about a quarter of the uniform samples.
    assert se_map[:, :10].max() <= 0.0105 and se_map[:, :10].mean() > 1.5 * out["uniform"][1][:, :10].mean()
    # Unbiased: the group means within 5 standard errors of their true values (1 and 3).
    for k, mu in enumerate((1.0, 3.0)):
        assert abs(mean[k].mean() - mu) < 5 * 0.02 * mu / np.sqrt(mean[k].size / 3)


def test_adaptive_accumulation_keeps_each_pixels_statistics_apart(rng):
    """A pixel given fewer batches (masked out of the rest) has the statistics of an accumulator that
    saw only its own batches: per-pixel sample counts, means, halves and errors."""
    mixtures = np.array([[1.0, 0.0], [0.0, 1.0]])
    both = BatchAccumulator(mixtures, floor_rel=1e-12, metric="absolute")
    alone = BatchAccumulator(mixtures, floor_rel=1e-12, metric="absolute")
    for b in range(12):
        images = rng.random((2, 1, 2, 1)) + 1.0
        mask = np.array([[True, b < 5]])
        shown = np.where(mask[None, ..., None], images, 0.0)
        both.add(shown, shown[..., 0], 4, mask=mask if b >= 5 else None)
        if b < 5:
            alone.add(images[:, :, 1:], images[:, :, 1:, 0], 4)
    np.testing.assert_array_equal(both.pixel_spp(), [[48, 20]])
    np.testing.assert_allclose(both.mean()[:, :, 1:], alone.mean(), rtol=1e-6)
    np.testing.assert_allclose(both.noise()[:, :, 1:], alone.noise(), rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(both.se_ln()[:, 1:], alone.se_ln(), rtol=1e-9)


def test_stop_rule_honours_max_spp_and_the_time_budget():
    scene = FakeScene(noise_target_ln=1e-4, max_spp=256)
    request = quality_request(scene.manifest.render, mixture_weights([(0.0, 2.0), (1.0, 1.0)]), 1e-4)
    _, _, _, report = render_pose(scene, request)
    assert report.stopped_by == "max_spp" and not report.reached and report.spp <= 256
    slow = FakeScene(noise_target_ln=1e-4, delay_s=0.02)
    request = quality_request(slow.manifest.render, mixture_weights([(0.0, 2.0), (1.0, 1.0)]), 1e-4)
    _, _, _, report = render_pose(slow, request, budget_s=0.5)
    assert report.stopped_by == "time_budget" and report.seconds < 1.0


def test_fixed_mode_renders_the_requested_samples():
    scene = FakeScene(spp=24)
    request = quality_request(scene.manifest.render, mixture_weights([(0.0, 2.0), (1.0, 1.0)]), None)
    _, noise, _, report = render_pose(scene, request)
    assert report.stopped_by == "fixed" and report.spp == 24 and report.batches % 2 == 0
    assert noise.std() > 0
    assert scene.one_pass_seen == {None}  # the scene's own choice


def test_render_pose_passes_the_one_pass_choice_to_every_batch():
    scene = FakeScene(spp=24)
    request = quality_request(scene.manifest.render, mixture_weights([(0.0, 2.0), (1.0, 1.0)]), None)
    _, _, _, report = render_pose(scene, request, one_pass=False)
    assert scene.one_pass_seen == {False} and report.spp == 24


def test_a_better_cached_render_serves_a_lesser_request():
    mix = mixture_weights([(0.0, 2.0), (1.0, 1.0)])
    settings = override(load("office"), spp=16).render
    fixed = quality_request(settings, mix, None)
    se_map = np.full((4, 4), 0.01)
    meta = {"spp": 64, "mixtures": mix.tolist(), "floor_rel": settings.noise_floor_rel, "metric": "flicker"}
    assert serves(meta, se_map, fixed)
    assert not serves({**meta, "spp": 8}, se_map, fixed)
    target = quality_request(override(load("office"), noise_target_ln=0.02).render, mix, 0.02)
    assert serves(meta, se_map, target)
    assert not serves(meta, np.full((4, 4), 0.03), target)
    assert not serves({**meta, "metric": "absolute"}, se_map, target)  # measured something else
    assert serves({**meta, "spp": target["max_spp"]}, np.full((4, 4), 0.03), target)  # no better to be had


@pytest.mark.parametrize("key, value, match", [
    ("noise_target_ln", 0.0, "render.noise_target_ln"),
    ("noise_target_ln", -1.0, "render.noise_target_ln"),
    ("max_spp", 0, "render.max_spp"),
    ("sampler", "sobolx", "render.sampler"),
    ("noise_percentile", 101.0, "render.noise_percentile"),
    ("noise_metric", "relative", "render.noise_metric"),
])
def test_bad_quality_settings_name_the_key(key, value, match):
    with pytest.raises(ConfigError, match=match):
        override(load("office"), **{key: value})


def test_bad_quality_settings_in_a_manifest_name_file_and_key(tmp_path):
    src = load("office").source
    text = open(src).read().replace("[render]", "[render]\nsampler = \"stratifed\"")
    text = text.replace("\nsampler = \"multijitter\"", "\n#")
    (tmp_path / "office.py").write_text(open(src.replace(".toml", ".py")).read())
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=r"bad.toml.*render.sampler.*stratified"):
        load(path)
    assert "noise_target_ln" in text  # the built-in scenes render to a noise target ...
    path.write_text(text.replace('sampler = "stratifed"', "spp = 8"))  # ... so a fixed spp beside it is ambiguous
    with pytest.raises(ConfigError, match="either spp"):
        load(path)


def test_spp_override_switches_to_the_fixed_mode():
    m = override(load("office"), noise_target_ln=0.01)
    assert m.render.targeted and "spp" not in m.raw["render"]
    m = override(m, spp=8)
    assert not m.render.targeted and m.render.spp == 8 and "noise_target_ln" not in m.raw["render"]


def test_extends_switches_the_quality_mode_like_an_override(tmp_path):
    """Issue 24 #18: a manifest that extends a noise-target scene with ``spp`` renders that fixed spp."""
    office = load("office")
    assert office.render.targeted
    child = tmp_path / "draft.toml"
    child.write_text(f'[scene]\nextends = "{office.source}"\n[render]\nspp = 8\n')
    m = load(child)
    assert not m.render.targeted and m.render.spp == 8 and m.builder == office.builder
    back = tmp_path / "back.toml"
    back.write_text('[scene]\nextends = "draft.toml"\n[render]\nnoise_target_ln = 0.01\n')
    m = load(back)
    assert m.render.targeted and m.render.noise_target_ln == 0.01 and "spp" not in m.raw["render"]


def test_a_render_stopped_by_its_time_budget_serves_the_same_budget_again():
    mix = mixture_weights([(0.0, 2.0), (1.0, 1.0)])
    request = quality_request(override(load("office"), noise_target_ln=0.001, time_budget_s=30.0).render, mix, 0.001)
    meta = {"spp": 64, "mixtures": mix.tolist(), "floor_rel": 1e-3, "metric": "flicker", "time_budget_s": 30.0,
            "report": {"stopped_by": "time_budget"}}
    assert serves(meta, np.full((4, 4), 0.01), request)
    assert not serves({**meta, "time_budget_s": 10.0}, np.full((4, 4), 0.01), request)
