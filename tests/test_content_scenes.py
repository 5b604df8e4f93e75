"""The 'scenes' content family (issue 47): each CG frame takes the cast and the brightness of one
of the camera's scenes, drawn per frame."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import g2r_jax
from g2r_jax import content
from g2r_jax.content import scenes
from g2r_jax.content.scene_statistics import LUMINANCE, ContentStatistics, statistics
from g2r_jax.pipeline import without_content
from g2r_jax.profile.schema import profile_from_dict, profile_to_dict, replace


def _real_statistics(n: int, seed: int = 0) -> ContentStatistics:
    rng = np.random.default_rng(seed)
    values = {name: rng.uniform(0.1, 0.3, n) for name in content.NAMES}
    values["cast_red"] = rng.normal(0.05, 0.15, n)
    values["cast_blue"] = rng.normal(-0.08, 0.15, n)
    values["brightness"] = rng.uniform(0.05, 0.4, n)
    return ContentStatistics(values=values, source="test files")


def _model(n: int = 40):
    return content.fit_content_model(_real_statistics(n), family="scenes")


def _frames(n: int = 3):
    """Blocky frames (8 x 8 blocks), so that a 64 x 64 area average keeps their peak like a CG
    frame's smooth surfaces do."""
    rng = np.random.default_rng(4)
    blocks = rng.uniform(0.0, 1.0, (n, 12, 16, 3)) ** 2 * np.float32([0.8, 1.0, 1.3])
    return np.kron(blocks, np.ones((1, 8, 8, 1))).astype(np.float32)


def test_fit_holds_the_files_scenes_from_one_file_on():
    model = _model(40)
    assert model.family == "scenes" and np.asarray(model.scene_casts).shape == (scenes.TABLE_SIZE, 3)
    assert np.allclose(np.asarray(model.scene_casts) @ LUMINANCE, 1.0, atol=1e-5)
    real = _real_statistics(40)
    held = np.asarray(model.scene_brightness)
    from_files = np.min(np.abs(held[:, None] - real.values["brightness"][None]), axis=1) < 1e-6
    # the files' scenes fill their share of the table, the prior's pseudo-files the rest
    assert from_files.mean() == np.mean(scenes.table_rows(40 + scenes.PRIOR_SCENES) < 40)
    alone = content.fitting.scenes_model(real, None, prior_scenes=0)
    assert np.all(np.min(np.abs(np.asarray(alone.scene_brightness)[:, None] - real.values["brightness"][None]), axis=1) < 1e-6)
    one_file = _real_statistics(1)
    one = content.fit_content_model(one_file, family="scenes")
    brightness = np.asarray(one.scene_brightness)
    assert one.family == "scenes" and dict(one.target)["scenes"] == 1.0 and dict(one.target)["prior_scenes"] == 5.0
    own = np.isclose(brightness, one_file.values["brightness"][0])
    assert own.mean() == np.mean(scenes.table_rows(1 + scenes.PRIOR_SCENES) < 1)
    assert len(set(brightness[~own].tolist())) == scenes.PRIOR_SCENES
    alone = content.fitting.scenes_model(one_file, None, prior_scenes=0)
    assert len(set(np.asarray(alone.scene_brightness).tolist())) == 1


def test_a_burst_of_one_scene_is_not_a_distribution_of_scenes():
    """40 frames of one scene (statistics within a burst's noise) are one scene in the table; the
    same frames among 30 distinct scenes count once."""
    rng = np.random.default_rng(1)
    one = _real_statistics(1)
    burst = {k: np.repeat(v, 40) + (rng.normal(0, 2e-3, 40) if k.startswith("cast") else 0.0)
             for k, v in one.values.items()}
    burst["brightness"] = burst["brightness"] * (1 + rng.normal(0, 5e-3, 40))
    assert dict(content.fit_content_model(ContentStatistics(values=burst), family="scenes").target)["scenes"] <= 2
    mixed = {k: np.concatenate([v, _real_statistics(30, seed=2).values[k]]) for k, v in burst.items()}
    model = content.fit_content_model(ContentStatistics(values=mixed), family="scenes")
    assert model.family == "scenes" and dict(model.target)["scenes"] <= 30 + 2


def test_each_frame_takes_its_drawn_scenes_cast_and_brightness():
    model = _model()
    frames = _frames()
    draws = np.float32([0.0, 0.5, 0.999])
    adapted = np.asarray(content.apply(model, frames, draws))
    rows = np.asarray(scenes.drawn_row(model, draws))
    assert rows.tolist() == [0, scenes.TABLE_SIZE // 2, scenes.TABLE_SIZE - 1]
    for image, row in zip(adapted, rows):
        mean = image.mean(axis=(0, 1))
        target = np.asarray(model.scene_casts)[row]
        grid = np.asarray(content.mean_grid(image))
        brightness = (grid @ LUMINANCE).mean() / grid.max()
        assert np.allclose(grid.mean(axis=(0, 1)) / (grid.mean(axis=(0, 1)) @ LUMINANCE), target, rtol=1e-4)
        assert brightness == pytest.approx(float(np.asarray(model.scene_brightness)[row]), rel=0.1)
        assert mean.min() > 0
    # the power keeps each pixel's chroma: a gain per channel apart, the ratios of the channels are the input's
    ratio = adapted[0] / np.maximum(frames[0], 1e-12)
    lit = (frames[0] @ LUMINANCE) > 0.05
    per_channel = ratio[lit] / ratio[lit][:, 1:2]
    assert np.allclose(per_channel, np.median(per_channel, axis=0), rtol=1e-3)


def test_the_scenes_family_needs_a_draw_and_round_trips_through_the_profile(tmp_path):
    model = content.with_default(_model(), True)
    with pytest.raises(ValueError, match="draw"):
        content.apply(model, _frames(1)[0])
    profile = replace(without_content(g2r_jax.load_profile("Canon600D")), content=model)
    back = profile_from_dict(profile_to_dict(profile)).content
    assert back.family == "scenes" and back.apply_by_default
    assert np.allclose(np.asarray(back.scene_casts), np.asarray(model.scene_casts), atol=1e-5)
    document = profile_to_dict(profile)
    document["content"]["scene_brightness"] = document["content"]["scene_brightness"][:-1]
    with pytest.raises(ValueError, match="scene_brightness"):
        profile_from_dict(document)


def test_unprocess_draws_a_scene_per_image_and_leaves_the_other_draws_alone():
    plain_profile = without_content(g2r_jax.load_profile("Canon600D"))
    profile = replace(plain_profile, content=content.with_default(_model(), True))
    image = (np.asarray(_frames(1)[0]) ** (1 / 2.2) * 255).astype(np.uint8)
    keys = jax.random.split(jax.random.PRNGKey(7), 4)
    mosaics, metadata = g2r_jax.unprocess_batch(keys, np.stack([image] * 4), profile)
    plain, plain_metadata = g2r_jax.unprocess_batch(keys, np.stack([image] * 4), plain_profile)
    assert np.allclose(np.asarray(metadata["neutral"]), np.asarray(plain_metadata["neutral"]))
    one, _ = g2r_jax.unprocess(keys[1], image, profile)
    assert np.array_equal(np.asarray(one), np.asarray(mosaics[1]))
    means = np.asarray(mosaics, np.float64).mean(axis=(1, 2))
    assert len(np.unique(np.round(means, 3))) == 4       # four draws, four scenes
    _, scene, _ = g2r_jax.unprocess(keys[1], image, profile, return_scene=True, noise=False)
    draw = jax.random.uniform(jax.random.fold_in(keys[1], g2r_jax.pipeline.CONTENT_STREAM), ())
    linear = np.asarray(g2r_jax.pipeline.decode(image, "srgb"))
    grid = np.asarray(g2r_jax.pipeline.decode(np.asarray(content.mean_grid(image)), "srgb"))
    assert np.allclose(np.asarray(scene), np.asarray(content.apply(profile.content, linear, draw, grid)), atol=1e-6)


def test_real_scenes_statistics_are_reached_by_frames():
    """The adapted frames' brightness, as the check measures it, is the drawn scene's where it lies
    below the frame's own (the highlights are only spread upward: a scene brighter than the frame
    does not darken it), and spreads like the table's rather than around one value."""
    model = _model()
    frames = np.repeat(_frames(1), 16, axis=0)
    draws = np.linspace(0.0, 0.99, 16).astype(np.float32)
    adapted = np.asarray(content.apply(model, frames, draws))
    measured = statistics(adapted).values["brightness"]
    wanted = np.asarray(model.scene_brightness)[np.asarray(scenes.drawn_row(model, draws))]
    own = statistics(frames[:1]).values["brightness"][0]
    reachable = wanted < 0.9 * own
    assert reachable.sum() >= 6
    assert np.allclose(measured[reachable], wanted[reachable], rtol=0.03)
    assert np.all(measured[~reachable] > 0.95 * own)   # not darkened (the cast's gains move it a little)
    assert np.std(measured) > 0.03


def test_as_cast_is_the_cast_model_of_the_same_files_and_convert_offers_it(tmp_path, capsys):
    real = _real_statistics(40)
    scenes_model = content.fit_content_model(real, family="scenes")
    cast_model = content.fit_content_model(real, family="cast")
    reduced = content.as_cast(scenes_model)
    assert reduced.family == "cast"
    assert np.allclose(np.asarray(reduced.cast_target), np.asarray(cast_model.cast_target), atol=1e-6)
    with pytest.raises(ValueError, match="holds no cast"):
        content.as_cast(content.content_model(0.5))

    import json

    from PIL import Image

    from g2r_jax.cli.convert import main as convert

    profile = replace(without_content(g2r_jax.load_profile("Canon600D")), content=content.with_default(scenes_model, True))
    (tmp_path / "profile.json").write_text(json.dumps(profile_to_dict(profile)))
    (tmp_path / "in").mkdir()
    Image.fromarray((np.asarray(_frames(1)[0]) ** (1 / 2.2) * 255).astype(np.uint8)).save(tmp_path / "in" / "a.png")
    assert convert([str(tmp_path / "in"), "--profile", str(tmp_path / "profile.json"), "-o", str(tmp_path / "out"),
                    "--content-cast-only", "--seed", "0"]) == 0
    said = capsys.readouterr()
    assert "content model: cast" in said.out + said.err


@pytest.mark.parametrize("colour, recipe", [("matrix", "dng"), ("spectral", "dng"), ("matrix", "published")])
def test_the_split_scenes_model_gives_the_mosaic_of_the_transformed_pixels(colour, recipe):
    """The 'scenes' model split for a linear colour stage (its gains in the matrix, its factor per
    pixel on the mosaic: `content.scenes_split`) gives the mosaic of the image transformed first;
    the published recipe's highlight easing is not linear and takes the transform on the pixels."""
    from g2r_jax.profile.editing import attach_spectral

    plain = without_content(g2r_jax.load_profile("Canon600D"))
    if colour != "matrix":
        plain = attach_spectral(plain)
    profile = replace(plain, content=content.with_default(_model(), True))
    linear = _frames(1)[0]
    options = dict(transfer="linear", noise=False, quantize=False, colour=colour, recipe=recipe)
    for index in range(3):
        key = jax.random.PRNGKey(index)
        mosaic, scene, _ = g2r_jax.unprocess(key, linear, profile, return_scene=True, **options)
        # the published recipe decodes its input with gamma 2.2 whatever the transfer
        again = np.asarray(scene) ** (1 / 2.2) if recipe == "published" else np.asarray(scene)
        transformed_first, _ = g2r_jax.unprocess(key, again, plain, **options)
        untouched, _ = g2r_jax.unprocess(key, linear, plain, **options)
        assert np.allclose(mosaic, transformed_first, rtol=1e-5, atol=1e-3)
        assert not np.allclose(mosaic, untouched, rtol=1e-3)


def test_the_split_is_a_factor_per_pixel_times_a_diagonal():
    model = _model()
    linear = _frames(1)[0]
    grid = content.mean_grid(linear)
    spreads = []
    for draw in (0.1, 0.3, 0.5, 0.7, 0.9):
        matrix, tone = content.scenes_split(model, draw, grid)
        assert np.count_nonzero(np.asarray(matrix) - np.diag(np.diag(np.asarray(matrix)))) == 0
        factor = np.asarray(content.pixel_factor(linear, tone))
        split = factor[..., None] * (linear @ np.asarray(matrix).T)
        assert np.allclose(split, np.asarray(content.apply(model, linear, draw, grid)), rtol=1e-6, atol=1e-7)
        spreads.append(np.ptp(factor))
    assert max(spreads) > 0.01    # the tone acts on some of these draws


def test_a_frame_the_curve_cannot_darken_is_not_raised_whole():
    """A flat frame lies wholly above its knee: no power lowers its brightness, so it keeps q = 1
    (only the cast's gains) rather than the range's end, which raised every pixel 128 times; a
    frame with a body below its knee still takes the power its drawn scene asks for."""
    model = _model()
    flat = np.full((64, 64, 3), 0.4, np.float32)
    grid = content.mean_grid(flat)
    for draw in (0.1, 0.5, 0.9):
        _, tone = content.scenes_split(model, draw, grid)
        assert float(np.asarray(tone[1]).reshape(())) == pytest.approx(1.0, abs=1e-4)
        out = np.asarray(content.apply(model, flat, draw, grid))
        assert out.max() < 0.4 * 1.5
    frame = _frames(1)[0]
    powers = [float(np.asarray(content.scenes_split(model, d, content.mean_grid(frame))[1][1]).reshape(()))
              for d in (0.1, 0.3, 0.5, 0.7, 0.9)]
    assert max(powers) > 1.05
