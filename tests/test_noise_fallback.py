"""Issue 8: DNGs without a usable NoiseProfile get their noise measured from their own pixels,
keep their ISO, and the profile says where its noise came from."""

from __future__ import annotations

import warnings

import jax
import numpy as np
import pytest

from g2r_jax.profile import fitting as fit
from g2r_jax.sensor.noise import extension as noise_extension, fallback as noise_fallback
from g2r_jax.audit import scenes, synthetic
from g2r_jax.profile.dng_tags import dng_info_for
from g2r_jax.io.dng_read import read_dng_info
from g2r_jax.io.dng_write import write_dng
from g2r_jax.pipeline import unprocess

ISO = 400.0
LEVELS = np.array([0.02, 0.1, 0.3, 0.6])


def _write_files(tmp_path, noise_profile, n=2, height=480, width=720):
    """DNGs of dead-leaves scenes with the demo camera's noise at ISO 400 injected, written with
    `noise_profile` as their NoiseProfile tag (None: no tag). Returns (paths, injected shot, read)."""
    profile = synthetic.demo_profile()
    paths = []
    for i in range(n):
        image = scenes.dead_leaves(20 + i, height, width, n_leaves=150, r_min=20.0)
        mosaic, meta = unprocess(jax.random.PRNGKey(i), image, profile, iso=ISO, exposure_gain=1.0, effects=False)
        info = dng_info_for(profile, meta, height, width, noise=False)
        info.noise_profile = noise_profile
        path = tmp_path / f"file{i}.dng"
        write_dng(path, np.asarray(mosaic), info)
        paths.append(path)
    return paths, np.asarray(meta["noise_shot"], np.float64), np.asarray(meta["noise_read"], np.float64)


def _fit(paths):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        profile = fit.fit_profile([read_dng_info(p) for p in paths])
    return profile, [str(w.message) for w in caught]


@pytest.mark.parametrize("tag, kind", [(None, "missing"), (np.zeros((3, 2)), "zero")])
def test_noise_measured_from_pixels_matches_injected(tmp_path, tag, kind):
    paths, shot, read = _write_files(tmp_path, tag)
    profile, messages = _fit(paths)
    assert np.asarray(profile.noise.iso).tolist() == [ISO]                       # the files' ISO, not 100
    assert np.asarray(profile.noise.iso_range).tolist() == [ISO, ISO]
    injected = shot[:, None] * LEVELS + read[:, None]
    fitted = noise_extension.predicted_variance(profile.noise, ISO, np.broadcast_to(LEVELS, (4, len(LEVELS))))
    assert np.all(np.abs(fitted / injected - 1) < 0.1), fitted / injected
    assert np.all(np.abs(np.asarray(profile.noise.shot[0]) / shot - 1) < 0.1)
    noise_lines = [m for m in messages if "NoiseProfile" in m]
    assert len(noise_lines) == 1 and "\n" not in noise_lines[0]
    assert f"{kind}: file0.dng, file1.dng" in noise_lines[0] and "measured from their pixels" in noise_lines[0]
    assert "measured from the pixels of 2 file(s)" in profile.info.provenance


def test_tags_used_when_usable_and_said_so(tmp_path):
    tag = np.array([[2e-4, 3e-6]] * 3)
    paths, _, _ = _write_files(tmp_path, tag, n=1, height=64, width=96)
    profile, messages = _fit(paths)
    assert not [m for m in messages if "NoiseProfile" in m]
    np.testing.assert_allclose(np.asarray(profile.noise.shot[0]), 2e-4, rtol=1e-6)
    assert "noise: NoiseProfile tags of 1 file(s) (ISO 400)" in profile.info.provenance


def test_degenerate_read_term_is_measured(tmp_path):
    """A NoiseProfile with O = 0 (Samsung S6 edge) is not used as is."""
    paths, shot, read = _write_files(tmp_path, np.array([[2e-4, 0.0]] * 3), n=1)
    profile, messages = _fit(paths)
    assert any("degenerate: file0.dng" in m for m in messages)
    assert np.all(np.asarray(profile.noise.read[0]) > 0.5 * read)
    assert np.all(np.abs(np.asarray(profile.noise.shot[0]) / shot - 1) < 0.15)


def test_degenerate_tag_without_pixels_gets_rounding_floor(tmp_path):
    info = read_dng_info(_write_files(tmp_path, np.array([[2e-4, 0.0]] * 3), n=1, height=64, width=96)[0][0])
    with pytest.warns(UserWarning, match="degenerate"):
        model, source = noise_fallback.noise_and_source([info], (0, 1, 1, 2), measure=False)
    floor = 1 / 12 / (4095.0 - 256.0) ** 2
    np.testing.assert_allclose(np.asarray(model.read[0]), floor, rtol=1e-5)
    assert "O raised to 1/12 DN^2" in source


@pytest.mark.data
def test_header_only_canon_350d_keeps_iso_and_warns_loudly(shared_data):
    """No NoiseProfile and pixel data cut short: no noise can be had; said loudly, ISO 400 kept."""
    info = read_dng_info(shared_data / "dng" / "canon_350d_header_only.dng")
    with pytest.warns(UserWarning, match="NO NOISE"):
        model, source = noise_fallback.noise_and_source([info], (0, 1, 1, 2))
    assert np.asarray(model.iso).tolist() == [400.0]
    assert source.startswith("noise: NONE")


@pytest.mark.slow
def test_small_files_pool_their_blocks(tmp_path):
    """8 files of 256 x 384 have too few flat blocks each for a noise level function, not
    together: the fallback pools their blocks and finds the injected noise."""
    paths, shot, read = _write_files(tmp_path, None, n=8, height=256, width=384)
    profile, messages = _fit(paths)
    assert "NONE" not in profile.info.provenance, profile.info.provenance
    injected = shot[:, None] * LEVELS + read[:, None]
    fitted = noise_extension.predicted_variance(profile.noise, ISO, np.broadcast_to(LEVELS, (4, len(LEVELS))))
    assert np.all(np.abs(fitted / injected - 1) < 0.15), fitted / injected


def test_a_warning_about_many_files_names_a_few_and_counts_the_rest():
    """A folder of 300 DNGs without usable noise tags: the warning names five files and counts
    the others, instead of 300 names (twice)."""
    import warnings

    from g2r_jax.sensor.noise import fallback

    names = [f"IMG_{i:04d}.dng" for i in range(300)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fallback._warn_unusable_profiles({"missing": names}, [(", ".join(names), "too few flat regions")], False)
    message = str(caught[0].message)
    assert "IMG_0000.dng, IMG_0001.dng" in message and "IMG_0005.dng" not in message
    assert message.count("and 295 more (300 files)") == 2 and len(message) < 400, message
    with warnings.catch_warnings(record=True) as few:
        warnings.simplefilter("always")
        fallback._warn_unusable_profiles({"missing": names[:2]}, [], True)
    assert "missing: IMG_0000.dng, IMG_0001.dng)" in str(few[0].message)
