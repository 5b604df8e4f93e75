"""Training and test sets of the downstream check: thumbnails, UPI, g2r_jax sets, the real-content
controls, a user's DNG folder and the content statistics."""

from __future__ import annotations

import numpy as np
import pytest

import g2r_jax
from g2r_jax.downstream.base import real_sets, thumbnails, training_sets, upi
from g2r_jax.downstream.illuminant import content
from g2r_jax.pipeline import without_content


def angle(a, b):
    a = np.asarray(a, np.float64) / np.linalg.norm(a, axis=-1, keepdims=True)
    b = np.asarray(b, np.float64) / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))


def textures(n, size=64, seed=0):
    """Grey-world-free random surfaces: smooth colour blobs in [0.05, 0.6]."""
    rng = np.random.default_rng(seed)
    coarse = rng.uniform(0.05, 0.6, (n, 8, 8, 3)).astype(np.float32)
    return np.repeat(np.repeat(coarse, size // 8, 1), size // 8, 2)


def test_mosaic_thumbnails_average_greens_zero_clipped_blocks_and_scale_to_one():
    cfa = np.array([1, 0, 2, 1])      # GRBG
    mosaic = np.zeros((1, 256, 256), np.float32)
    values = {0: 0.2, 1: 0.4, 2: 0.1}
    black, white = 64.0, 1023.0
    for site, colour in enumerate(cfa):
        mosaic[0, site // 2::2, site % 2::2] = black + values[colour] * (white - black)
    mosaic[0, :2, :2] = white                               # one clipped CFA tile in block (0, 0)
    thumbs = np.asarray(thumbnails.mosaic_thumbnails(mosaic, cfa, black, white))
    assert thumbs.shape == (1, 64, 64, 3)
    assert np.all(thumbs[0, 0, 0] == 0)
    np.testing.assert_allclose(thumbs[0, 5, 7], np.array([0.2, 0.4, 0.1]) / 0.4, rtol=1e-5)


def test_camera_rgb_thumbnail_takes_any_size_and_area_averages():
    rgb = np.full((130, 197, 3), 0.25, np.float32)
    rgb[:, :, 2] = 0.5
    thumb = thumbnails.camera_rgb_thumbnail(rgb)
    assert thumb.shape == (64, 64, 3)
    np.testing.assert_allclose(thumb[10, 10], [0.5, 0.5, 1.0], rtol=1e-5)
    with pytest.raises(ValueError, match="smaller"):
        thumbnails.camera_rgb_thumbnail(np.ones((40, 80, 3), np.float32))


def test_upi_labels_a_grey_scene_with_its_own_colour():
    """UPI's rows of the camera matrix sum to 1: a grey surface takes the colour of 1 / gains."""
    import jax

    grey = np.full((64, 64, 3), 0.4, np.float32)
    for seed in range(5):
        camera, light = upi.unprocess_rgb(jax.random.PRNGKey(seed), grey, noise=False)
        assert angle(np.asarray(camera).reshape(-1, 3).mean(0), light) < 0.05
        gains = 1 / np.asarray(light)
        assert 1.9 <= gains[0] <= 2.4 and 1.5 <= gains[2] <= 1.9


def test_g2r_set_records_a_grey_view_at_the_neutral_it_is_labelled_with():
    profile = without_content(g2r_jax.load_profile("NikonD40"))   # grey in, grey out: no CG content model
    views = np.full((6, 128, 128, 3), 0.18, np.float32)
    neutrals = np.array([[0.45, 1, 0.8], [0.7, 1, 0.45], [0.5, 1, 0.6]] * 2)
    thumbs, lights = training_sets.g2r_set(views, profile, 0, neutrals=neutrals)
    np.testing.assert_allclose(lights, neutrals / neutrals[:, 1:2], rtol=1e-5)
    assert np.all(angle(thumbs.reshape(6, -1, 3).mean(1), neutrals) < 0.5)
    _, drawn = training_sets.g2r_set(views, profile, 0)
    assert np.ptp(drawn[:, 0]) > 0.01                      # drawn from the profile's illuminant model


def test_real_content_round_trip_keeps_each_image_and_relighting_moves_it():
    """Rendered to sRGB at its light and made RAW again under the same light, a real image's
    thumbnail comes back (noise and clipping aside); under another light its colour moves."""
    profile = without_content(g2r_jax.load_profile("NikonD40"))   # real content: no CG content model
    lights = np.array([[0.5, 1, 0.7], [0.75, 1, 0.45], [0.55, 1, 0.62], [0.8, 1, 0.4]])
    real = textures(4) * lights[:, None, None, :]
    real = real / real.reshape(4, -1).max(1)[:, None, None, None]
    views = training_sets.real_to_linear_srgb(real, lights, profile)
    back, _ = training_sets.g2r_set(views, profile, 1, neutrals=lights)
    lit = (back.reshape(-1, 3) > 0).all(1)                 # clipped pixels are zeroed
    assert lit.mean() > 0.8
    assert np.median(angle(back.reshape(-1, 3)[lit], real.reshape(-1, 3)[lit])) < 1.0
    moved, _ = training_sets.g2r_set(views, profile, 1, neutrals=lights[::-1])
    lit = (moved.reshape(-1, 3) > 0).all(1)
    assert np.median(angle(moved.reshape(-1, 3)[lit], real.reshape(-1, 3)[lit])) > 5.0


def test_padded_illuminant_model_draws_from_the_same_distribution():
    import jax

    from g2r_jax.illuminants.distributions import fit_mixture, sample_neutrals

    rng = np.random.default_rng(0)
    points = np.concatenate([rng.normal([0.5, 0.7], 0.02, (30, 2)), rng.normal([0.8, 0.4], 0.02, (30, 2))])
    model = fit_mixture(points)
    padded = training_sets._padded_model(model)
    assert padded.weights.shape[0] >= 8 and padded.hull.shape[0] % 32 == 0
    a = np.asarray(sample_neutrals(jax.random.PRNGKey(1), model, 4000))
    b = np.asarray(sample_neutrals(jax.random.PRNGKey(2), padded, 4000))
    np.testing.assert_allclose(a.mean(0), b.mean(0), atol=0.01)
    np.testing.assert_allclose(a.std(0), b.std(0), atol=0.01)


def test_cg_views_refuse_small_images_and_keep_shape():
    images = [np.random.default_rng(0).random((150, 200, 3)).astype(np.float32)]
    views = training_sets.cg_views(images, 5, 0)
    assert views.shape == (5, 128, 128, 3) and 0 <= views.min() and views.max() <= 1
    with pytest.raises(ValueError, match="smaller than the 128"):
        training_sets.cg_views([np.zeros((100, 300, 3), np.float32)], 2, 0)


def test_content_statistics_name_what_differs():
    """A set whose surfaces are greyer and darker than the real one's: chroma spread and
    brightness are the statistics that differ, in the right direction."""
    lights = np.tile([[0.5, 1, 0.7]], (40, 1))
    vivid = textures(40, seed=1) * lights[:, None, None, :]
    rng = np.random.default_rng(2)
    grey = (0.1 + 0.05 * rng.random((40, 64, 64, 1))) * np.ones(3) * lights[:, None, None, :]
    grey[:, 0, 0] = lights                                 # same brightest pixel: brightness is relative
    vivid = vivid / vivid.reshape(40, -1).max(1)[:, None, None, None]
    rows = {r["statistic"]: r for r in content.compare((grey, lights), (vivid, lights), (vivid, lights))}
    assert rows["chroma_spread"]["distance"] < -3
    assert rows["brightness"]["distance"] < -3
    assert not rows["zeroed_share"]["spread"] and np.isnan(rows["zeroed_share"]["distance"])   # 0 everywhere
    assert rows["chroma_spread"]["control_distance"] == 0 and rows["chroma_spread"]["excess"] > 3


def test_content_statistics_without_spread_are_reported_as_such_not_as_distances():
    """Issue 34: a real set with no dark pixels anywhere, or whose saturated pixels all read 0 in
    the same share, gave distances of thousands of robust sd. Now every distance is floored at the
    statistic's resolution, a statistic without spread gives no distance, and none exceeds 100."""
    from g2r_jax.downstream.illuminant import reporting

    lights = np.tile([[0.5, 1, 0.7]], (30, 1))
    real = textures(30, seed=3) * lights[:, None, None, :]
    real = real / real.reshape(30, -1).max(1)[:, None, None, None]
    real[:, :20, :17] = 0.0                                    # the same clipped-as-zero share in every file
    synthetic = textures(30, seed=4) * lights[:, None, None, :]
    synthetic[:, 40:, :, :] *= 0.01                            # a dark share the real files never have
    rows = {r["statistic"]: r for r in content.compare((synthetic, lights), (real, lights))}
    for name in ("dark_share", "zeroed_share"):
        assert not rows[name]["spread"] and np.isnan(rows[name]["distance"]) and np.isnan(rows[name]["excess"])
    assert rows["dark_share"]["synthetic"] > 0.3 and rows["dark_share"]["real"] == 0
    finite = [abs(r["distance"]) for r in rows.values() if r["spread"]]
    assert finite and max(finite) < 100
    assert "no spread in the real files" in reporting.content_table(list(rows.values()))
    assert content.resolution("dark_share", 4096, 0.0) == 1 / 4096
    assert content.resolution("zeroed_share", 4096, 0.085) == pytest.approx(np.sqrt(0.085 * 0.915 / 4096))


def test_dng_folder_is_read_with_as_shot_labels_and_bad_files_named(tmp_path):
    from g2r_jax.audit import scenes, simulate
    from g2r_jax.io.dng_write import write_dng

    profile = g2r_jax.load_profile("NikonD40")
    files = simulate.simulate(profile, scenes.scene_set(3, 5, 160, 240), 3)
    for i, (mosaic, info) in enumerate(files):
        write_dng(tmp_path / f"f{i}.dng", mosaic, info)
    (tmp_path / "broken.dng").write_bytes(b"II*\x00not a dng")
    real, skipped = real_sets.load_dng_folder([tmp_path])
    assert real.images.shape == (3, 64, 64, 3) and real.label == real_sets.DNG_LABEL
    expected = np.stack([info.as_shot_neutral for _, info in files])
    np.testing.assert_allclose(real.illuminants, expected / expected.sum(1, keepdims=True), rtol=1e-4)
    assert [p for p, _ in skipped] == [str(tmp_path / "broken.dng")]


@pytest.mark.data
def test_nus_set_loads_with_measured_labels(shared_data):
    real = real_sets.load_nus(shared_data / "estimation" / "nus" / "NikonD40.npz")
    assert real.images.shape == (117, 64, 64, 3)
    np.testing.assert_allclose(real.illuminants.sum(1), 1.0)


def test_nus_loader_names_the_file_it_refuses(tmp_path):
    bad = tmp_path / "bad.npz"
    np.savez(bad, images=np.zeros((3, 32, 32, 3)), illuminants=np.ones((3, 3)))
    with pytest.raises(ValueError, match="bad.npz"):
        real_sets.load_nus(bad)


def test_light_and_cast_statistics_read_known_scenes():
    """Issue 47: the share near the top of the range, the spread of the light in stops and the
    mean surface's cast under a neutral light, on scenes built to have them; the spread ratio of a
    set with one cast against one with spread casts."""
    lights = np.tile([[0.5, 1, 0.7]], (20, 1))
    image = np.full((20, 64, 64, 3), 0.1)
    image[:, :32] = 1.0                                      # half the frame at the top, half 3.32 stops down
    rng = np.random.default_rng(5)
    casts = np.c_[rng.normal(0.1, 0.2, 20), rng.normal(-0.2, 0.2, 20)]
    tint = np.exp(np.c_[casts[:, 0], np.zeros(20), casts[:, 1]])
    spread = image * tint[:, None, None, :] * lights[:, None, None, :]
    spread /= spread.reshape(20, -1).max(1)[:, None, None, None]
    values = content.image_statistics(spread, lights)
    np.testing.assert_allclose(values["cast_red"], casts[:, 0], atol=1e-6)
    np.testing.assert_allclose(values["cast_blue"], casts[:, 1], atol=1e-6)
    np.testing.assert_allclose(values["light_spread"], np.log2(10) / 2, atol=0.02)
    assert np.all(values["bright_share"] >= 0.49) and np.all(values["bright_share"] <= 0.51)
    one = image * np.exp([0.1, 0.0, -0.2]) * lights[:, None, None, :]
    rows = {r["statistic"]: r for r in content.compare((one / one.max(), lights), (spread, lights))}
    assert rows["cast_red"]["spread_ratio"] < 0.1 and rows["cast_blue"]["spread_ratio"] < 0.1
