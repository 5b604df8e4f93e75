"""The content model (g2r_jax.content): statistics, the transform, fitting without labels, JSON."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax import content
from g2r_jax.content import prior
from g2r_jax.content.scene_statistics import LUMINANCE


def _colourful(n=12, size=64, seed=0):
    """Linear sRGB images of random coloured blocks (8 x 8 pixels each) on a random brightness."""
    rng = np.random.default_rng(seed)
    blocks = rng.uniform(0.05, 1.0, (n, size // 8, size // 8, 3))
    return np.repeat(np.repeat(blocks, 8, 1), 8, 2).astype(np.float32)


def test_identity_returns_its_input_bit_for_bit():
    images = _colourful()
    assert np.array_equal(np.asarray(content.apply(content.identity(), images)), images)


def test_chroma_scale_keeps_luminance_and_neutrals_and_greys_at_zero():
    images = _colourful()
    half = np.asarray(content.apply(content.content_model(0.5), images))
    np.testing.assert_allclose(half @ LUMINANCE, images @ LUMINANCE, rtol=1e-5, atol=1e-6)
    assert half.min() >= 0
    grey = np.full((1, 64, 64, 3), 0.3, np.float32)
    np.testing.assert_allclose(content.apply(content.content_model(0.2), grey), grey, rtol=1e-6)
    none = np.asarray(content.apply(content.content_model(0.0), images))
    np.testing.assert_allclose(none[..., 0], none[..., 2], rtol=1e-5)
    np.testing.assert_allclose(half - (images @ LUMINANCE)[..., None],
                               0.5 * (images - (images @ LUMINANCE)[..., None]), atol=1e-6)


def test_tone_power_keeps_the_peak_and_darkens_the_body():
    images = _colourful()
    darker = np.asarray(content.apply(content.content_model(1.0, 2.0, family="chroma_tone"), images))
    np.testing.assert_allclose(darker.max(axis=(1, 2, 3)), images.max(axis=(1, 2, 3)), rtol=1e-6)
    assert np.all(darker.mean(axis=(1, 2, 3)) < images.mean(axis=(1, 2, 3)))


def test_cast_zero_removes_each_images_own_tint_and_keeps_its_luminance():
    # von Kries: an image tinted by a diagonal gain t (sum of w t = 1) is brought back to its
    # untinted self when the untinted image's mean is neutral
    rng = np.random.default_rng(3)
    neutral_mean = rng.uniform(0.05, 1.0, (3, 64, 64, 1)) * np.ones(3, np.float32)   # grey images
    colourful = _colourful(3, seed=4)
    base = (neutral_mean + colourful - colourful.mean(axis=(1, 2), keepdims=True)).clip(0.0, None).astype(np.float32)
    base *= (base.mean(axis=(1, 2), keepdims=True) @ LUMINANCE)[..., None] / base.mean(axis=(1, 2), keepdims=True)
    tints = rng.uniform(0.5, 1.5, (3, 1, 1, 3))
    tints /= (tints @ LUMINANCE)[..., None]
    tinted = (base * tints).astype(np.float32)
    removed = np.asarray(content.apply(content.content_model(cast_scale=0.0, family="cast"), tinted))
    np.testing.assert_allclose(removed, base, rtol=2e-5, atol=1e-6)
    means = removed.mean(axis=(1, 2))
    np.testing.assert_allclose(means, np.repeat(means[:, 1:2], 3, 1), rtol=2e-5)
    np.testing.assert_allclose(means @ LUMINANCE, tinted.mean(axis=(1, 2)) @ LUMINANCE, rtol=2e-5)


def test_cast_kept_scales_the_tint_geometrically_and_one_changes_nothing():
    images = _colourful(4, seed=5) * np.array([1.4, 1.0, 0.6], np.float32)
    assert np.array_equal(np.asarray(content.apply(content.content_model(cast_scale=1.0, family="cast"), images)), images)
    half = np.asarray(content.apply(content.content_model(cast_scale=0.5, family="cast"), images))
    cast_before = np.log(images.mean(axis=(1, 2)) / images.mean(axis=(1, 2))[:, 1:2])
    cast_half = np.log(half.mean(axis=(1, 2)) / half.mean(axis=(1, 2))[:, 1:2])
    np.testing.assert_allclose(cast_half, 0.5 * cast_before, atol=1e-4)   # float32 means
    dark_channel = images.copy()
    dark_channel[..., 2] = 0.0                    # a channel whose mean is 0 keeps gain 1, no NaN
    out = np.asarray(content.apply(content.content_model(cast_scale=0.0, family="cast"), dark_channel))
    assert np.all(np.isfinite(out)) and np.all(out[..., 2] == 0.0)


def test_cast_target_takes_each_images_mean_to_that_colour():
    images = _colourful(3, seed=6) * np.array([0.7, 1.0, 1.4], np.float32)     # blue, like the CARLA frames
    warm = content.content_model(cast_scale=0.0, cast_target=(1.1, 1.0, 0.8), family="cast")
    target = np.asarray(warm.cast_target)
    assert float(target @ LUMINANCE) == pytest.approx(1.0, rel=1e-6)       # scaled to luminance 1
    means = np.asarray(content.apply(warm, images)).mean(axis=(1, 2))
    luminance = images.mean(axis=(1, 2)) @ LUMINANCE
    np.testing.assert_allclose(means, luminance[:, None] * target[None], rtol=3e-5)


def test_the_cast_fit_takes_the_real_images_median_cast_through_the_camera_matrix():
    rng = np.random.default_rng(7)
    real = _colourful(20, seed=8) * np.exp(rng.normal([0.06, 0.0, -0.1], 0.02, (20, 1, 1, 3))).astype(np.float32)
    stats = content.statistics(real, source="warm scenes")
    to_camera = np.array([[1.1, -0.05, -0.05], [0.02, 0.96, 0.02], [-0.03, -0.07, 1.1]])
    to_camera /= to_camera.sum(1, keepdims=True)                         # white to white
    model = content.fit_content_model(stats, family="cast", to_camera=to_camera)
    assert model.family == "cast" and float(model.cast_scale) == content.CAST_KEPT and "warm scenes" in model.source
    in_camera = to_camera @ np.asarray(model.cast_target, np.float64)
    shrunk = []                                   # 20 files: their median pulled toward the prior's
    for name in ("cast_red", "cast_blue"):
        spread = prior.CAST_SPREAD[name]
        weight = 20 / (20 + np.pi / 2 * (spread["per_image"] / spread["between_cameras"]) ** 2)
        shrunk.append(weight * stats.median(name) + (1 - weight) * prior.REAL_SCENES["medians"][name])
    np.testing.assert_allclose(in_camera / in_camera[1], np.exp([shrunk[0], 0.0, shrunk[1]]), rtol=1e-5)
    one = content.fit_content_model(content.statistics(real[:1]), family="cast", to_camera=to_camera)
    one_cast = np.log((to_camera @ np.asarray(one.cast_target, np.float64))[[0, 2]] /
                      (to_camera @ np.asarray(one.cast_target, np.float64))[1])
    np.testing.assert_allclose(one_cast, [prior.REAL_SCENES["medians"]["cast_red"],
                                          prior.REAL_SCENES["medians"]["cast_blue"]], atol=0.005)   # one scene: the prior
    assert stats.median("cast_red") > 0.03 and stats.median("cast_blue") < -0.05   # the cast it was made with
    prior_model = content.fit_content_model(None, family="cast")
    assert "NUS" in prior_model.source
    np.testing.assert_allclose(np.log(np.asarray(prior_model.cast_target)[[0, 2]] / float(prior_model.cast_target[1])),
                               [prior.REAL_SCENES["medians"]["cast_red"], prior.REAL_SCENES["medians"]["cast_blue"]],
                               rtol=1e-5)
    assert content.as_matrix(model) is None and "cast" in content.describe(model)
    with pytest.raises(ValueError, match="cast_scale"):
        content.content_model(cast_scale=-0.1, family="cast")
    with pytest.raises(ValueError, match="cast_target"):
        content.content_model(cast_target=(1.0, 0.0, 1.0), family="cast")


def test_apply_jits_and_vmaps_with_the_model_as_an_argument():
    images = jnp.asarray(_colourful(4))
    run = jax.jit(jax.vmap(content.apply, in_axes=(None, 0)))
    np.testing.assert_allclose(run(content.content_model(0.4), images),
                               content.apply(content.content_model(0.4), images), rtol=1e-6)


def test_bad_parameters_are_refused_with_their_name():
    with pytest.raises(ValueError, match="chroma_scale"):
        content.content_model(1.5)
    with pytest.raises(ValueError, match="tone_power"):
        content.content_model(1.0, 0.0)
    with pytest.raises(ValueError, match="family"):
        content.fit_content_model(family="hue_magic")


def test_chroma_spread_of_grey_is_zero_and_scales_with_small_chroma():
    grey = np.broadcast_to(np.linspace(0.05, 1.0, 64, dtype=np.float32)[None, :, None, None], (2, 64, 64, 3))
    assert content.statistics(grey).median("chroma_spread") == pytest.approx(0.0, abs=1e-9)
    images = _colourful(20, seed=1)
    mild = np.asarray(content.apply(content.content_model(0.2), images))
    milder = np.asarray(content.apply(content.content_model(0.1), images))
    ratio = content.statistics(milder).median("chroma_spread") / content.statistics(mild).median("chroma_spread")
    assert ratio == pytest.approx(0.5, rel=0.1)


def test_statistics_count_dark_and_clipped_pixels():
    image = np.full((1, 64, 64, 3), 0.2, np.float32)
    image[0, :16] = 0.001          # a quarter dark
    image[0, 16:24] = 1.0          # an eighth at the peak
    stats = content.statistics(image)
    assert stats.values["dark_share"][0] == pytest.approx(0.25)
    assert stats.values["clipped_share"][0] == pytest.approx(0.125)
    with pytest.raises(ValueError, match="non-finite"):
        content.statistics(np.full((1, 64, 64, 3), np.nan, np.float32), source="bad.dng")
    with pytest.raises(ValueError, match="too small|H, W >= 64"):
        content.statistics(np.zeros((1, 32, 32, 3), np.float32))


def test_fit_recovers_the_chroma_scale_that_made_the_real_images():
    cg = _colourful(40, seed=2)
    real = np.asarray(content.apply(content.content_model(0.45), _colourful(40, seed=3)))
    model = content.fit_content_model(content.statistics(real), cg_sample=cg)
    assert model.family == "chroma"
    assert float(model.chroma_scale) == pytest.approx(0.45, abs=0.05)
    by_medians = content.fit_content_model(content.statistics(real), content.statistics(cg))
    assert float(by_medians.chroma_scale) == pytest.approx(0.45, abs=0.1)


def test_fit_never_adds_colour():
    cg = np.asarray(content.apply(content.content_model(0.3), _colourful(20, seed=4)))
    model = content.fit_content_model(content.statistics(_colourful(20, seed=5)), cg_sample=cg)
    assert float(model.chroma_scale) == 1.0


def test_tone_fit_matches_the_brightness():
    cg = _colourful(30, seed=6)
    real = np.asarray(content.apply(content.content_model(1.0, 1.8, family="chroma_tone"), _colourful(30, seed=7)))
    model = content.fit_content_model(content.statistics(real), family="chroma_tone", cg_sample=cg)
    assert float(model.tone_power) == pytest.approx(1.8, abs=0.15)


def test_without_images_the_priors_are_used_and_named():
    model = content.fit_content_model(None, None)
    assert "NUS" in model.source and "CARLA" in model.source
    expected = prior.REAL_SCENES["medians"]["chroma_spread"] / prior.REFERENCE_CG["medians"]["chroma_spread"]
    assert float(model.chroma_scale) == pytest.approx(min(1.0, expected), rel=1e-6)


def test_json_round_trip_and_clear_errors():
    model = content.content_model(0.4, 1.2, family="chroma_tone", source="test", target={"chroma_spread": 0.2},
                                  apply_by_default=True)
    document = json.loads(json.dumps(content.content_to_dict(model)))
    back = content.content_from_dict(document)
    assert float(back.chroma_scale) == pytest.approx(0.4) and float(back.tone_power) == pytest.approx(1.2)
    assert back.family == "chroma_tone" and back.apply_by_default is True and back.source == "test"
    assert dict(back.target) == {"chroma_spread": pytest.approx(0.2)}
    cast = content.content_from_dict(content.content_to_dict(
        content.content_model(cast_scale=0.0, cast_target=(1.05, 1.0, 0.9), family="cast")))
    assert cast.family == "cast" and float(cast.cast_scale) == 0.0
    assert np.asarray(cast.cast_target)[2] < np.asarray(cast.cast_target)[0]
    older = {k: v for k, v in document.items() if k != "cast_scale"}   # blocks written before the family
    assert float(content.content_from_dict(older).cast_scale) == 1.0
    for bad, where in (({**document, "family": "x"}, "content.family"),
                       ({**document, "chroma_scale": "half"}, "content.chroma_scale"),
                       ({**document, "chroma_scale": 2.0}, "content"),
                       ({**document, "cast_scale": 1.5}, "content"),
                       ({**document, "cast_target": [1, 1]}, "content.cast_target"),
                       ({**document, "texture": {"covariance": [[1, 0], [0, 1]]}}, "content.texture"),
                       ({**document, "texture": [1, 2]}, "content.texture"),
                       ({**document, "cast_target": [1, -1, 1]}, "content"),
                       ({**document, "apply_by_default": "yes"}, "content.apply_by_default"),
                       ({**document, "extra": 1}, "unknown keys")):
        with pytest.raises(ValueError, match=where):
            content.content_from_dict(bad)


def test_real_images_round_trip_through_the_camera_matrices():
    import g2r_jax

    profile = g2r_jax.load_profile("Canon600D")
    srgb = _colourful(3, seed=8)
    neutrals = np.array([[0.5, 1.0, 0.7], [0.6, 1.0, 0.5], [0.45, 1.0, 0.8]])
    to_camera = content.srgb_to_camera_matrices(neutrals, profile.colour)
    raw = np.einsum("nij,nhwj->nhwi", to_camera, srgb) * neutrals[:, None, None, :]
    back = content.camera_rgb_to_linear_srgb(raw, neutrals, profile.colour)
    np.testing.assert_allclose(back, srgb / srgb.reshape(3, -1).max(1)[:, None, None, None], atol=2e-3)
    with pytest.raises(ValueError, match="neutrals"):
        content.white_balanced_camera_rgb(raw, -neutrals)


@pytest.mark.slow
def test_prior_numbers_are_those_of_the_data(shared_data):
    real = prior.measure_real_scenes(shared_data)
    cg = prior.measure_reference_cg(shared_data)
    for key in ("chroma_spread", "brightness", "cast_red", "cast_blue"):
        assert prior.REAL_SCENES["medians"][key] == pytest.approx(real[key], rel=1e-3)
        assert prior.REFERENCE_CG["medians"][key] == pytest.approx(cg[key], rel=1e-3)
    np.testing.assert_allclose(prior.SCENE_SPREAD["covariance"], prior.scene_covariance(shared_data), atol=1e-5)
    np.testing.assert_allclose(prior.SCENE_TEXTURE["covariance"], prior.texture_covariance(shared_data), atol=1e-4)
    assert not np.allclose(prior.texture_covariance(shared_data, "SonyA57"), prior.SCENE_TEXTURE["covariance"], atol=1e-5)


def test_leaving_a_camera_out_of_the_prior_names_a_camera_it_does_not_know(tmp_path):
    with pytest.raises(ValueError, match="'GoProHero6' is not a NUS camera"):
        prior.real_scenes_without(tmp_path, "GoProHero6")


@pytest.mark.data
def test_a_camera_left_out_of_the_prior_moves_its_cast_target_little(shared_data):
    """The median of the other eight cameras' medians lies within the nine cameras' spread of the
    prior (CAST_SPREAD's between-camera sd, twice) and differs from it for some camera."""
    moved = []
    for camera in ("PanasonicGX1", "SonyA57"):
        left_out = prior.real_scenes_without(shared_data, camera)
        for key in ("cast_red", "cast_blue"):
            shift = abs(left_out[key] - prior.REAL_SCENES["medians"][key])
            assert shift <= 2 * prior.CAST_SPREAD[key]["between_cameras"], (camera, key, shift)
            moved.append(shift)
    assert max(moved) > 1e-4


def test_the_prior_scenes_model_spreads_about_the_prior_and_keeps_its_cast():
    """A profile without files gets a table of scenes drawn from the prior (`prior_scenes_model`):
    its medians are the prior's, so its median cast is the cast model's; its casts and
    brightness spread as one camera's scenes do; a given seed gives the same table."""
    import g2r_jax
    from g2r_jax.content.scene_statistics import LUMINANCE

    colour = g2r_jax.load_profile("Canon600D").colour
    model = content.prior_scenes_model(colour)
    assert model.family == "scenes" and len(np.asarray(model.scene_brightness)) == 64
    np.testing.assert_allclose(np.asarray(content.as_cast(model).cast_target),
                               np.asarray(content.prior_cast_model(colour).cast_target), atol=1e-6)
    brightness = np.asarray(model.scene_brightness)
    assert np.median(brightness) == pytest.approx(prior.REAL_SCENES["medians"]["brightness"], rel=0.05)
    spread = np.std(np.log(brightness))
    assert 0.5 < spread / np.sqrt(prior.SCENE_SPREAD["covariance"][2][2]) < 1.5
    casts = np.asarray(model.scene_casts)
    np.testing.assert_allclose(casts @ LUMINANCE, 1.0, atol=1e-5)
    assert np.std(np.log(casts[:, 2] / casts[:, 1])) > 0.05
    again = content.prior_scenes_model(colour)
    assert np.array_equal(np.asarray(again.scene_casts), casts)
    other = content.prior_scenes_model(colour, seed=1)
    assert not np.array_equal(np.asarray(other.scene_casts), casts)


@pytest.mark.data
def test_a_camera_left_out_of_the_scene_spread_changes_it_little(shared_data):
    with pytest.raises(ValueError, match="not a NUS camera"):
        prior.scene_covariance(shared_data, "GoProHero6")
    left_out = prior.scene_covariance(shared_data, "SonyA57")
    shipped = np.asarray(prior.SCENE_SPREAD["covariance"])
    assert not np.allclose(left_out, shipped, atol=1e-6)
    np.testing.assert_allclose(np.sqrt(np.diag(left_out)), np.sqrt(np.diag(shipped)), rtol=0.2)
