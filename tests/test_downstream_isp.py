"""The neural-ISP task (issue 42): the LibRaw reference renderer, the packing of every CFA phase,
the measures against known values, files left out by name, too small a set refused, and a tiny
run of every row."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import g2r_jax
from g2r_jax.downstream.isp import net, pairs, task
from g2r_jax.io import reference_render
from g2r_jax.io.dng_info import DngError

BAYER = {"RGGB": (0, 1, 1, 2), "GRBG": (1, 0, 2, 1), "GBRG": (1, 2, 0, 1), "BGGR": (2, 1, 1, 0)}


@pytest.fixture(scope="module")
def profile():
    return g2r_jax.load_profile("NikonD40")


def _sources(profile, count: int, seed: int = 0):
    """`count` small DNGs of smooth random scenes under lights near daylight."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:64, 0:64] / 64.0
    images = np.stack([np.clip(0.2 + 0.5 * rng.random(3) * (np.sin(6 * x + k) * 0.5 + 0.5)[..., None]
                               + 0.2 * rng.random(3) * y[..., None], 0.01, 0.95) for k in range(count)]).astype(np.float32)
    lights = np.c_[rng.uniform(0.4, 0.7, count), np.ones(count), rng.uniform(0.5, 0.8, count)]
    return pairs.thumbnail_sources(images, lights, profile), images, lights


def test_renderer_is_deterministic_and_honours_the_as_shot_white(profile):
    source = _sources(profile, 1)[0][0]
    first, second = reference_render.develop(source.data), reference_render.develop(source.data)
    assert first.shape == (64, 64, 3) and first.dtype == np.float32
    assert np.array_equal(first, second) and 0.0 <= first.min() and first.max() <= 1.0
    # a grey surface: every site at the light's channel ratios, AsShotNeutral that light -> grey out
    from g2r_jax.profile.dng_tags import dng_info_for

    neutral = np.array([0.5, 1.0, 0.7])
    flat = pairs.tile_mosaic(pairs.rgb_planes(np.broadcast_to(0.3 * neutral, (32, 32, 3))), profile.cfa_pattern,
                             profile.black_level, profile.white_level)
    info = dng_info_for(profile, pairs._metadata(neutral), 64, 64, noise=False)
    grey = reference_render.develop(pairs.dng_source(flat, info, "grey.dng").data)[16:48, 16:48].mean((0, 1))
    assert np.ptp(grey) < 0.01, grey
    wrong = dng_info_for(profile, pairs._metadata(np.array([1.0, 1.0, 1.0])), 64, 64, noise=False)
    tinted = reference_render.develop(pairs.dng_source(flat, wrong, "tinted.dng").data)[16:48, 16:48].mean((0, 1))
    assert np.ptp(tinted) > 0.05, tinted


def test_renderer_develops_a_real_camera_file_and_its_working_copy(shared_data):
    path = shared_data / "dng" / "gopro_hero6_GOPR0024.dng"
    image = reference_render.develop(path)
    assert image.shape[:2] == (3000, 4000) and np.array_equal(image, reference_render.develop(path.read_bytes()))
    small = pairs.working_source(path)
    assert small.mosaic.shape == (64, 64) and small.info.cfa_pattern == (0, 1, 1, 2)
    from g2r_jax.io.dng_read import read_dng_info

    tags = read_dng_info(path)
    assert np.allclose(small.info.as_shot_neutral, tags.as_shot_neutral) and small.info.white_level == tags.white_level
    packed, target = pairs.pair_of(small)
    assert packed.shape == (32, 32, 4) and target.shape == (64, 64, 3)
    assert 0.01 < packed.mean() < 1.0 and 0.01 < target.mean() < 1.0
    # the working copy holds the file's binned colour: its target is close to the binned development
    binned = np.stack([np.mean(image[y * 94:(y + 1) * 94, x * 125:(x + 1) * 125], (0, 1)) for y in range(32)
                       for x in range(32)]).reshape(32, 32, 3)
    assert np.abs(target[::2, ::2].mean((0, 1)) - binned.mean((0, 1))).max() < 0.08


@pytest.mark.parametrize("name", sorted(BAYER))
def test_packing_gives_r_g1_g2_b_for_every_phase(name):
    cfa = BAYER[name]
    values = {"R": 0.1, "G1": 0.4, "G2": 0.6, "B": 0.9}
    black, white = 64.0, 1023.0
    mosaic = np.zeros((4, 6))
    red_row = cfa.index(0) // 2
    for p, colour in enumerate(cfa):
        label = "RGB"[colour] if colour != 1 else ("G1" if p // 2 == red_row else "G2")
        mosaic[p // 2::2, p % 2::2] = black + values[label] * (white - black)
    packed = pairs.pack(mosaic, cfa, black, white)
    assert packed.shape == (2, 3, 4)
    assert np.allclose(packed[0, 0], [values[k] for k in ("R", "G1", "G2", "B")], atol=1e-6)
    planes = np.random.default_rng(1).random((3, 5, 4))
    back = pairs.pack(pairs.tile_mosaic(planes, cfa, black, white), cfa, black, white)
    assert np.allclose(back, planes, atol=1 / (white - black))


def test_a_pattern_that_is_not_bayer_is_refused():
    with pytest.raises(ValueError, match="not a 2x2 Bayer"):
        pairs.channel_positions((0, 0, 1, 2))


def test_psnr_ssim_and_delta_e_against_known_values():
    rng = np.random.default_rng(0)
    x = rng.random((2, 32, 32, 3)) * 0.8
    assert np.allclose(net.ssim(x, x), 1.0)
    assert np.allclose(net.psnr(x, x + 0.1), 20.0)                     # MSE 0.01
    a, b = np.full((1, 16, 16, 1), 0.5), np.full((1, 16, 16, 1), 0.25)     # flat: only the luminance term
    c1 = 0.01 ** 2
    assert np.allclose(net.ssim(a, b), (2 * 0.5 * 0.25 + c1) / (0.5 ** 2 + 0.25 ** 2 + c1))
    noise = rng.normal(0, 1, x.shape)
    slightly, badly = net.ssim(x, x + 0.05 * noise), net.ssim(x, x + 0.3 * noise)
    assert np.all(badly < slightly) and np.all(slightly < 0.99)
    white, black = np.ones((1, 12, 12, 3)), np.zeros((1, 12, 12, 3))
    assert np.allclose(net.delta_e_2000(white, black), 100.0, atol=1e-3)   # L* 100 against 0, S_L = 1
    assert np.allclose(net.delta_e_2000(x, x), 0.0)
    with pytest.raises(ValueError, match="SSIM needs"):
        net.ssim(x[:, :8, :8], x[:, :8, :8])


def test_a_dng_the_renderer_cannot_develop_is_left_out_by_name(profile, tmp_path):
    sources = _sources(profile, 2)[0]
    broken = tmp_path / "broken.dng"
    broken.write_bytes(b"II*\x00" + bytes(200))
    with pytest.raises(DngError, match="bad.dng"):
        reference_render.develop(b"not a raw file", name="bad.dng")
    packed, targets, kept, skipped = pairs.pairs_of([sources[0], broken, sources[1]])
    assert list(kept) == [0, 2] and len(packed) == len(targets) == 2
    assert len(skipped) == 1 and skipped[0][0] == str(broken) and skipped[0][1]


def test_too_few_files_for_the_folds_are_refused(profile):
    from g2r_jax.downstream.base.real_sets import RealSet

    sources, images, lights = _sources(profile, 4)
    real = RealSet(name="tiny", images=images, illuminants=lights / lights.sum(1, keepdims=True))
    with pytest.raises(ValueError, match=r"tiny: 4 usable real DNG.*at least 6"):
        task.run_isp_task(real, profile, [np.zeros((64, 64, 3), np.uint8)], dngs=sources, folds=3)
    with pytest.raises(ValueError, match="unknown rows"):
        task.run_isp_task(real, profile, [], dngs=sources, rows=("upi", "nope"))


def test_views_of_the_wrong_size_are_refused(profile):
    with pytest.raises(ValueError, match=r"views must be \(n, 32, 32, 3\)"):
        pairs.g2r_pairs(np.zeros((2, 64, 64, 3), np.float32), profile, 0)


def test_a_tiny_run_of_upi_and_real_training(profile):
    from g2r_jax.downstream.base.real_sets import RealSet

    sources, images, lights = _sources(profile, 6)
    real = RealSet(name="tiny", images=images, illuminants=lights / lights.sum(1, keepdims=True))
    cg = [(np.random.default_rng(k).random((40, 48, 3)) * 255).astype(np.uint8) for k in range(2)]
    training = net.IspTraining(steps=2, steps_per_round=2, batch=2, width=2)
    result = task.run_isp_task(real, profile, cg, rows=("upi", "real"), seeds=(0, 1), n=4, dngs=sources,
                               training=training)
    assert result.images == 6 and result.seeds == (0, 1)
    for key, per_seed in result.metrics.items():
        assert len(per_seed) == 2 and all(v.shape == (6,) and np.all(np.isfinite(v)) for v in per_seed), key
    assert "`upi`" in result.table() and "`real`" in result.table()
    assert "UPI" in result.sentence() and "real training" in result.sentence()
    summary = result.summary("real", "psnr")
    assert summary["seed_min"] <= summary["mean"] <= summary["seed_max"]
    assert result.examples["target"].shape == (task.EXAMPLES, 64, 64, 3)


@pytest.mark.slow
def test_a_tiny_run_measures_every_row(tmp_path):
    from PIL import Image

    from downstream_helpers import write_camera_folders
    from g2r_jax.downstream.base.real_sets import load_dng_folder

    dngs, cg_folder = write_camera_folders(tmp_path, 6, 2)
    real, skipped = load_dng_folder([dngs])
    assert not skipped and len(real.images) == 6
    cg = [np.asarray(Image.open(p).convert("RGB")) for p in sorted(cg_folder.glob("*.png"))]
    profile = g2r_jax.load_profile("NikonD40")
    training = net.IspTraining(steps=2, steps_per_round=2, batch=2, width=4)
    result = task.run_isp_task(real, profile, cg, rows=tuple(task.ROWS), seeds=(0,), n=6, training=training)
    for row in task.ROWS:
        for metric in task.METRICS:
            values = result.metrics[(row, metric)]
            assert len(values) == 1 and values[0].shape == (6,) and np.all(np.isfinite(values[0])), (row, metric)
    table, sentence = result.table(), result.sentence()
    assert all(f"`{row}`" in table for row in task.ROWS)
    assert "UPI" in sentence and "real training" in sentence and "profile's share" in sentence
    assert result.to_dict()["summary"]["fitted/psnr"]["seed_means"]
    assert any("content model" in note for note in result.notes)
    assert any("texture" in note for note in result.notes)          # the fitted and single rows' files' texture
    # with the texture the fitted 'scenes' model is kept whole, after the texture
    assert any("each frame's cast and brightness" in n for n in result.notes)
    from g2r_jax.pipeline import without_content
    fitted = task.run_isp_task(real, without_content(profile), cg, rows=("fitted",), seeds=(0,), n=6, training=training,
                               texture=False)
    assert not any("texture" in note for note in fitted.notes)
    content_notes = [n for n in fitted.notes if "fitted to" in n]
    assert content_notes and all(": cast, each frame" in n for n in content_notes), content_notes
    assert result.figure(tmp_path / "isp.png") and (tmp_path / "isp.png").stat().st_size > 1000
    packed, target = pairs.pair_of(real.files[0])     # a camera file from its path: binned to the task's size
    assert packed.shape == (32, 32, 4) and target.shape == (64, 64, 3) and 0.0 < target.mean() < 1.0


@pytest.mark.slow
def test_rows_trained_together_match_one_at_a_time(profile):
    sources = _sources(profile, 4)[0]
    packed, targets, _, _ = pairs.pairs_of(sources)
    sets = [(packed[:3], targets[:3]), (packed[1:], targets[1:])]
    config = dict(steps=2, steps_per_round=2, batch=2, width=2)
    apart = net.train_many(sets, [0, 1], net.IspTraining(together=False, **config))
    together = net.train_many(sets, [0, 1], net.IspTraining(together=True, **config))
    for a, b in zip(apart, together):
        assert np.allclose(net.predict(a, packed), net.predict(b, packed), atol=1e-4)


def test_masks_cover_what_a_masked_pixel_reaches_in_the_target(profile):
    """A thumbnail pixel stored as 0 (masked chart, saturation) changes the developed target only
    where `thumbnail_masks` says, and the mask leaves the rest."""
    images = np.full((1, 64, 64, 3), 0.3, np.float32)
    holed = images.copy()
    holed[0, 20:23, 30:31] = 0.0                      # takes in two tiles: rows 10-11, column 15
    light = np.array([[0.5, 1.0, 0.6]])
    plain, masked = (reference_render.develop(pairs.thumbnail_sources(x, light, profile)[0].data)
                     for x in (images, holed))
    changed = np.abs(plain - masked).max(-1) > 1e-4
    mask = pairs.thumbnail_masks(holed)[0]
    assert changed.any() and not np.any(changed & mask)
    assert (~mask).sum() == 6 * 4                     # two tiles (4 x 2 pixels) spread by one pixel
    assert pairs.thumbnail_masks(images).all()


def test_masked_measures_ignore_the_masked_pixels():
    rng = np.random.default_rng(3)
    target = rng.random((2, 32, 32, 3))
    predicted = target + 0.01 * rng.standard_normal(target.shape)
    mask = np.ones((2, 32, 32), bool)
    mask[:, 4:12, 20:30] = False
    spoiled = predicted.copy()
    spoiled[:, 4:12, 20:30] = 1.0 - target[:, 4:12, 20:30]          # wrong only where masked
    clean, wrong = net.measure(predicted, target, mask), net.measure(spoiled, target, mask)
    for metric in task.METRICS:
        np.testing.assert_allclose(wrong[metric], clean[metric], rtol=1e-9, err_msg=metric)
    unmasked = net.measure(spoiled, target)
    assert np.all(unmasked["psnr"] < clean["psnr"] - 3) and np.all(unmasked["delta_e"] > clean["delta_e"])
    np.testing.assert_allclose(net.measure(predicted, target, np.ones((2, 32, 32), bool))["psnr"],
                               net.psnr(predicted, target))
    assert np.isnan(net.psnr(predicted, target, np.zeros((2, 32, 32), bool))).all()


def test_masked_pixels_are_out_of_the_loss(profile):
    """Training on pairs whose masked pixels hold nonsense gives the same network as training on
    the same pairs with those pixels set to anything else."""
    sources = _sources(profile, 4)[0]
    packed, targets, _, _ = pairs.pairs_of(sources)
    mask = np.ones(targets.shape[:3], bool)
    mask[:, 10:30, 5:40] = False
    other = targets.copy()
    other[:, 10:30, 5:40] = 1.0 - other[:, 10:30, 5:40]
    config = net.IspTraining(steps=3, steps_per_round=3, batch=2, width=2, together=False)
    a, b = (net.train_many([(packed, t, mask)], [0], config)[0] for t in (targets, other))
    np.testing.assert_allclose(net.predict(a, packed), net.predict(b, packed), atol=1e-6)
    c = net.train_many([(packed, other)], [0], config)[0]
    assert not np.allclose(net.predict(a, packed), net.predict(c, packed), atol=1e-4)


def test_saturated_tiles_are_written_at_the_white_level(profile):
    views = np.full((2, 32, 32, 3), 0.2, np.float32)
    tiles = np.zeros((2, 32, 32), bool)
    tiles[1, 3:6, 10:12] = True
    images = np.full((2, 64, 64, 3), 0.3, np.float32)
    images[1, 6:12, 20:24] = 0.0
    assert np.array_equal(pairs.missing_tiles(images), tiles)
    lights = np.array([[0.5, 1, 0.6]] * 2)
    packed, targets = pairs.g2r_pairs(views, profile, 0, neutrals=lights, saturated=tiles)
    plain, _ = pairs.g2r_pairs(views, profile, 0, neutrals=lights)
    assert np.all(packed[1][tiles[1]] == 1.0) and not np.any(plain[1][tiles[1]] == 1.0)
    assert np.array_equal(packed[1][~tiles[1]], plain[1][~tiles[1]]) and np.array_equal(packed[0], plain[0])
    assert targets[1][7:11, 21:23].min() > 0.99          # developed white inside, as the real pairs' missing pixels


def test_the_mixed_row_holds_both_sets_and_only_the_real_pairs_masks():
    real = (np.zeros((3, 4, 4, 4)), np.zeros((3, 8, 8, 3)), np.zeros((3, 8, 8), bool))
    synthetic = (np.ones((5, 4, 4, 4)), np.ones((5, 8, 8, 3)))
    packed, targets, masks = task._mixed(real, synthetic)
    assert packed.shape == (8, 4, 4, 4) and targets.shape == (8, 8, 8, 3)
    assert not masks[:3].any() and masks[3:].all() and packed[3:].min() == 1
    assert len(task._mixed(real[:2], synthetic)) == 2
    assert "real_plus_fitted" in task.ROWS and "real_plus_fitted" not in task.DEFAULT_ROWS


def test_fine_tuning_starts_from_the_given_network(profile):
    sources = _sources(profile, 4)[0]
    packed, targets, _, _ = pairs.pairs_of(sources)
    config = net.IspTraining(steps=2, steps_per_round=2, batch=2, width=2, together=False)
    pretrained = net.train_many([(packed, targets)], [3], config)[0]
    frozen = dataclasses.replace(config, learning_rate=0.0)
    kept = net.train_many([(packed, targets)], [0], frozen, initial=[pretrained])[0]
    np.testing.assert_allclose(net.predict(kept, packed), net.predict(pretrained, packed), atol=1e-6)
    fresh = net.train_many([(packed, targets)], [0], frozen)[0]
    assert not np.allclose(net.predict(fresh, packed), net.predict(pretrained, packed), atol=1e-4)
    with pytest.raises(ValueError, match="initial"):
        net.train_many([(packed, targets)], [0], frozen, initial=[])


def test_the_control_row_holds_the_real_inputs_where_the_masks_hide_the_targets(profile):
    from g2r_jax.downstream.base.real_sets import RealSet

    _, images, lights = _sources(profile, 6)
    images[:, 10:15, 20:27] = 0.0                     # missing pixels, as the NUS thumbnails store them
    real = RealSet(name="test", images=images, illuminants=lights)
    masks = pairs.thumbnail_masks(images)
    real, real_pairs, _, _ = task._real_pairs(real, pairs.thumbnail_sources(images, lights, profile), 64, 3, masks)
    sets = task._RowSets(real, real_pairs, profile, profile, np.zeros((1, 64, 64, 3), np.float32), n=6, size=64,
                         view_size=32, illuminant_model="auto", single_light="auto", lights=None, masks=real_pairs[2])
    train = np.arange(6)
    packed, _, control_masks = sets.build("real_profile_light", train, 0, 0)
    hidden = ~control_masks[:, ::2, ::2]
    assert hidden.any() and np.array_equal(control_masks, masks)
    assert np.array_equal(packed[hidden], real_pairs[0][hidden])
    assert not np.allclose(packed[~hidden], real_pairs[0][~hidden], atol=1e-3)   # elsewhere: made again


def test_the_fitted_rows_views_carry_their_files_texture():
    from g2r_jax.downstream.base.real_sets import RealSet

    profile = g2r_jax.load_profile("NikonD40")
    rng = np.random.default_rng(0)
    images = np.clip(rng.uniform(0.05, 0.9, (6, 64, 64, 3)), 0, 1).astype(np.float32)   # rough real scenes
    lights = np.c_[rng.uniform(0.4, 0.7, 6), np.ones(6), rng.uniform(0.5, 0.8, 6)]
    real = RealSet(name="rough", images=images, illuminants=lights / lights.sum(1, keepdims=True))
    real, real_pairs, _, _ = task._real_pairs(real, pairs.thumbnail_sources(images, lights, profile), 64, 3)
    flat_cg = [np.full((64, 64, 3), 0.3, np.float32)] * 2

    def fitted_inputs(texture: bool):
        sets = task._RowSets(real, real_pairs, profile, profile, flat_cg, n=8, size=64, view_size=32,
                             illuminant_model="auto", single_light="auto", lights=None, texture=texture)
        packed = sets.build("fitted", np.arange(6), 0, 0)[0]
        return packed, sets.notes

    (plain, plain_notes), (rough, rough_notes) = fitted_inputs(False), fitted_inputs(True)
    contrast = lambda p: np.median(np.abs(np.diff(np.log(p[..., 1] + 1e-3), axis=2)))
    assert contrast(plain) < 1e-3 < 0.05 < contrast(rough)
    assert not any("texture" in n for n in plain_notes) and any("texture" in n for n in rough_notes)
