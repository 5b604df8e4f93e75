"""The content model where a user meets it: profiles (with and without the block), unprocess,
g2r-fit-profile and g2r-convert."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest

import g2r_jax
from g2r_jax import content
from g2r_jax.pipeline import without_content
from g2r_jax.profile.editing import attach_spectral
from g2r_jax.profile.schema import profile_from_dict, profile_to_dict, replace


def _image():
    return np.random.default_rng(0).integers(0, 256, (32, 48, 3)).astype(np.uint8)


def test_a_profile_without_a_content_model_converts_exactly_as_before():
    profile = without_content(g2r_jax.load_profile("Canon600D"))
    assert profile.content is None and "content" not in profile_to_dict(profile)
    key = jax.random.PRNGKey(3)
    plain, _ = g2r_jax.unprocess(key, _image(), profile)
    unchanged, _ = g2r_jax.unprocess(key, _image(), profile, content=False)
    off_by_default, _ = g2r_jax.unprocess(key, _image(), replace(profile, content=content.content_model(0.3)))
    assert np.array_equal(plain, unchanged) and np.array_equal(plain, off_by_default)
    with pytest.raises(ValueError, match="no content model"):
        g2r_jax.unprocess(key, _image(), profile, content=True)


def test_the_content_model_changes_the_mosaic_when_on():
    profile = without_content(g2r_jax.load_profile("Canon600D"))
    key = jax.random.PRNGKey(3)
    plain, _ = g2r_jax.unprocess(key, _image(), profile)
    on_by_default = replace(profile, content=content.content_model(0.3, apply_by_default=True))
    adapted, metadata = g2r_jax.unprocess(key, _image(), on_by_default)
    forced, _ = g2r_jax.unprocess(key, _image(), replace(profile, content=content.content_model(0.3)), content=True)
    turned_off, _ = g2r_jax.unprocess(key, _image(), on_by_default, content=False)
    assert not np.array_equal(plain, adapted)
    assert np.array_equal(adapted, forced) and np.array_equal(plain, turned_off)
    batch, _ = g2r_jax.unprocess_batch(key[None], _image()[None], on_by_default)
    assert np.array_equal(batch[0], adapted)


@pytest.mark.parametrize("colour, family", [("matrix", "chroma"), ("spectral", "chroma"),
                                            ("spectral-jakob2019", "chroma"), ("matrix", "chroma_tone"),
                                            ("matrix", "cast")])
def test_folded_content_model_equals_the_transform_of_the_pixels(colour, family):
    """A linear model folded into the colour matrix (no pass over the pixels) gives the mosaic of
    the image transformed first ('cast': a diagonal matrix of each image's gains); 'chroma_tone'
    (not linear) and the Jakob-Hanika stage (not a matrix) take the transform on the pixels."""
    profile = without_content(g2r_jax.load_profile("Canon600D"))
    if colour != "matrix":
        profile = attach_spectral(profile)
    model = content.content_model(0.35, 1.3 if family == "chroma_tone" else 1.0, family=family,
                                  cast_scale=0.0 if family == "cast" else 1.0)
    assert (content.as_matrix(model) is None) == (family in ("chroma_tone", "cast"))
    if family == "cast":
        assert content.as_matrix(model, np.ones((4, 4, 3), np.float32)) is not None
    linear = np.random.default_rng(1).uniform(0.0, 1.0, (32, 48, 3)).astype(np.float32) * np.float32([1.3, 1.0, 0.7])
    key = jax.random.PRNGKey(5)
    options = dict(transfer="linear", noise=False, quantize=False, colour=colour)
    in_the_model, _ = g2r_jax.unprocess(key, linear, replace(profile, content=model), content=True, **options)
    transformed_first, _ = g2r_jax.unprocess(key, np.asarray(content.apply(model, linear)), profile, **options)
    plain, _ = g2r_jax.unprocess(key, linear, profile, **options)
    assert np.allclose(in_the_model, transformed_first, rtol=1e-5, atol=1e-3)
    assert not np.allclose(in_the_model, plain, rtol=1e-3)


def test_as_matrix_is_the_chroma_transform():
    linear = np.random.default_rng(2).uniform(0.0, 2.0, (5, 7, 3)).astype(np.float32)
    for model in (content.content_model(0.35), content.identity()):
        assert np.allclose(linear @ np.asarray(content.as_matrix(model)).T, content.apply(model, linear), atol=1e-6)


def test_profile_json_round_trip_keeps_the_model_and_names_a_bad_block(tmp_path):
    profile = replace(g2r_jax.load_profile("Canon600D"), content=content.content_model(0.5, source="test"))
    document = json.loads(json.dumps(profile_to_dict(profile)))
    back = profile_from_dict(document, "cam.json")
    assert float(back.content.chroma_scale) == pytest.approx(0.5) and back.content.apply_by_default is False
    document["content"]["chroma_scale"] = -1
    with pytest.raises(Exception, match=r"cam\.json.*content"):
        profile_from_dict(document, "cam.json")


def test_mosaic_thumbnail_zeroes_clipped_blocks_and_refuses_small_mosaics():
    mosaic = np.full((256, 256), 1000, np.uint16)
    mosaic[:8, :8] = 4095
    thumb = content.mosaic_thumbnail(mosaic, (0, 1, 1, 2), 0, 4095)
    assert thumb.shape == (64, 64, 3) and np.all(thumb[0, 0] == 0) and thumb[10, 10, 1] == pytest.approx(1000 / 4095)
    with pytest.raises(ValueError, match="smaller"):
        content.mosaic_thumbnail(mosaic[:100], (0, 1, 1, 2), 0, 4095)


def test_fit_from_files_goes_on_past_a_bad_file():
    rng = np.random.default_rng(1)
    good = lambda: (rng.integers(100, 3000, (256, 256)), (0, 1, 1, 2), 64, 4095, np.array([0.5, 1.0, 0.6]))
    files = {"a.dng": good(), "b.dng": good(), "broken.dng": None, "tiny.dng": (np.zeros((10, 10)), (0, 1, 1, 2), 0, 4095,
                                                                           np.ones(3))}

    def read(name):
        if files[name] is None:
            raise OSError("cannot read")
        return files[name]

    problems = []
    model, used = content.content_model_from_files(list(files), read, on_error=lambda f, p: problems.append(f))
    assert used == 2 and sorted(problems) == ["broken.dng", "tiny.dng"]
    assert model is not None and 0.0 <= float(model.chroma_scale) <= 1.0
    assert model.texture is not None and model.texture.files == 2     # the files' texture, for an ISP's pairs
    assert np.all(np.diag(model.texture.covariance) > 0)
    back = content.content_from_dict(content.content_to_dict(model))
    assert np.allclose(back.texture.covariance, model.texture.covariance, atol=1e-6)
    assert content.as_cast(model).texture == model.texture if model.family in ("cast", "scenes") else True
    assert content.content_model_from_files(["broken.dng"], read) == (None, 0)


@pytest.mark.slow
def test_fit_profile_stores_the_scenes_model_on_and_convert_follows_the_flags(tmp_path, capsys):
    from g2r_jax.cli import convert, fit_profile

    dngs = tmp_path / "dngs"
    assert convert.main(["--example", "--profile", "gopro_hero6", "-o", str(dngs), "--quiet"]) == 0
    assert fit_profile.main([str(dngs), "-o", str(tmp_path / "cam.json")]) == 0
    said = capsys.readouterr().out
    assert "content model: scenes, each frame's cast and brightness those of one of 1 real scene (" in said
    assert "from 1 file(s)' scenes (their median cast weighs 1%/2% red/blue, the rest the prior" in said
    block = json.loads((tmp_path / "cam.json").read_text())["content"]
    assert block["family"] == "scenes" and block["apply_by_default"] is True and "1 DNG file(s)" in block["source"]
    assert len(block["cast_target"]) == 3 and len(block["scene_casts"]) == len(block["scene_brightness"]) == 64
    assert block["texture"]["files"] == 1 and len(block["texture"]["covariance"]) == 3    # for an ISP's pairs
    assert fit_profile.main([str(dngs), "-o", str(tmp_path / "plain.json"), "--no-content-model"]) == 0
    assert "content" not in json.loads((tmp_path / "plain.json").read_text())
    document = json.loads((tmp_path / "cam.json").read_text())
    document["content"]["apply_by_default"] = False
    (tmp_path / "off.json").write_text(json.dumps(document))

    def converted(profile, flags, name):
        assert convert.main(["--example", "--profile", str(profile), "-o", str(tmp_path / name), "--quiet"] + flags) == 0
        return (tmp_path / name / "colour_checker_scene.dng").read_bytes()

    on = {flags: converted(tmp_path / "cam.json", list(flags), f"on{i}")
          for i, flags in enumerate(((), ("--no-content-model",), ("--content-model",)))}
    assert on[()] == on[("--content-model",)] != on[("--no-content-model",)]
    off = {flags: converted(tmp_path / "off.json", list(flags), f"off{i}")
           for i, flags in enumerate(((), ("--no-content-model",), ("--content-model",)))}
    assert off[()] == off[("--no-content-model",)] != off[("--content-model",)]
    assert off[("--no-content-model",)] == on[("--no-content-model",)]
    manifest = lambda name: json.loads((tmp_path / name / "manifest.jsonl").read_text().splitlines()[0])
    assert manifest("on0")["content_model"].startswith("scenes, ")              # says what the scene went through
    assert "content_model" not in manifest("on1") and "content_model" not in manifest("off0")


def test_a_shipped_profile_applies_its_content_model_by_default(tmp_path):
    from g2r_jax.cli import convert

    def converted(flags, name):
        assert convert.main(["--example", "--profile", "Canon600D", "-o", str(tmp_path / name), "--quiet"] + flags) == 0
        return (tmp_path / name / "colour_checker_scene.dng").read_bytes()

    default, forced, off = converted([], "default"), converted(["--content-model"], "on"), converted(
        ["--no-content-model"], "off")
    assert default == forced != off
    manifest = json.loads((tmp_path / "default" / "manifest.jsonl").read_text().splitlines()[0])
    assert manifest["content_model"].startswith("scenes, ")


def test_convert_content_model_on_a_profile_without_one_uses_the_prior_and_says_so(tmp_path, capsys):
    from g2r_jax.cli import convert
    from g2r_jax.profile.schema import save_profile

    profile = without_content(g2r_jax.load_profile("Canon600D"))
    save_profile(profile, tmp_path / "plain.json")
    assert convert.main(["--example", "--profile", str(tmp_path / "plain.json"), "-o", str(tmp_path / "plain"),
                         "--quiet"]) == 0
    assert convert.main(["--example", "--profile", str(tmp_path / "plain.json"), "-o", str(tmp_path / "cast"),
                         "--content-model"]) == 0
    err = capsys.readouterr().err
    assert "no content model: using the prior of real scenes'" in err and "content model: scenes" in err
    name = "colour_checker_scene.dng"
    assert (tmp_path / "plain" / name).read_bytes() != (tmp_path / "cast" / name).read_bytes()
    model = content.prior_scenes_model(profile.colour)
    assert model.family == "scenes" and "NUS" in content.prior.SCENE_SPREAD["source"]
