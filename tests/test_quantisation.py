"""Rounding to integer DN counted once: a read term measured from integer raws has the rounding
variance (1/12 DN^2) taken out, the profile says so, and a simulated dark frame then holds the
variance the real one was measured with."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax.io.dng_info import DngInfo
from g2r_jax.io.dng_read import read_dng_info
from g2r_jax.io.dng_write import write_dng
from g2r_jax.pipeline import unprocess
from g2r_jax.profile.checks import ProfileError
from g2r_jax.profile.fitting import fit_profile
from g2r_jax.profile.schema import load_profile, profile_to_dict, save_profile
from g2r_jax import sensor
from g2r_jax.sensor.noise.quantisation import rounding_variance, without_quantisation

BLACK, WHITE = 64.0, 1023.0           # a 10-bit sensor
SPAN = WHITE - BLACK
CM_D65 = np.array([[0.6787, -0.1641, -0.0811], [-0.3936, 1.1934, 0.1660], [-0.1016, 0.2686, 0.4541]])


def real_dark_frame_variance(sigma_dn: float, shape=(512, 512), seed=1) -> float:
    """What a real camera's dark frame holds: analogue read noise, then the ADC rounds to integers."""
    frame = np.round(BLACK + sigma_dn * np.random.default_rng(seed).standard_normal(shape))
    return float(frame.var())


def sensor_info(noise_profile, path="") -> DngInfo:
    return DngInfo(path=path, cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, BLACK), white_level=WHITE,
                   unique_camera_model="G2R 10-bit", calibration_illuminants=(21,), color_matrices=(CM_D65,),
                   as_shot_neutral=np.array([0.55, 1.0, 0.6]), noise_profile=noise_profile, iso=100.0)


def simulated_dark_frame_variance(profile, shape=(512, 512)) -> float:
    """The simulation's dark frame, by its own noise and digitisation steps (as `unprocess` runs them)."""
    shot, read = sensor.noise_parameters(100.0, profile.noise)
    noisy = sensor.add_noise(jax.random.PRNGKey(3), jnp.zeros(shape, jnp.float32), shot, read)
    mosaic = sensor.to_digital_numbers(noisy, profile.black_level, profile.white_level, profile.effects)
    return float(np.asarray(mosaic, np.float64).var())


def pipeline_dark_frame_variance(profile, shape=(256, 256)) -> float:
    """The same through the whole pipeline: a black image converted at ISO 100."""
    black_image = np.zeros(shape + (3,), np.float32)
    mosaic, _ = unprocess(jax.random.PRNGKey(3), black_image, profile, transfer="linear", iso=100.0,
                          exposure_gain=1.0, effects=False)
    return float(np.asarray(mosaic, np.float64).var())


def test_rounding_variance_in_normalised_units():
    np.testing.assert_allclose(rounding_variance(np.full(4, BLACK), WHITE), 1 / 12 / SPAN**2, rtol=1e-12)


@pytest.mark.parametrize("sigma_dn", [0.5, 1.0])
def test_dark_frame_from_a_noise_profile_tag_matches_the_measurement(tmp_path, sigma_dn):
    """A DNG whose NoiseProfile O is the measured dark variance (rounding included), fitted and
    simulated: the simulated dark frame holds the measured variance (within 4 %). Counting the
    rounding twice made the real frame hold 0.80x the simulated variance at 0.5 DN."""
    measured = real_dark_frame_variance(sigma_dn)
    path = tmp_path / "dark.dng"
    write_dng(path, np.full((32, 48), int(BLACK), np.uint16),
              sensor_info(np.array([[1e-4, measured / SPAN**2]])))
    profile = fit_profile([read_dng_info(path)])
    assert profile.noise.read_excludes_quantisation
    np.testing.assert_allclose(np.asarray(profile.noise.read), (measured - 1 / 12) / SPAN**2, rtol=1e-5)
    simulated = simulated_dark_frame_variance(profile)
    assert abs(simulated / measured - 1) < 0.04, (measured, simulated)


@pytest.mark.slow
def test_pipeline_dark_frame_matches_the_measurement():
    """The same check through `unprocess` (a black image): 0.5 DN on 10 bits."""
    measured = real_dark_frame_variance(0.5)
    profile = fit_profile([sensor_info(np.array([[1e-4, measured / SPAN**2]]), "dark.dng")])
    simulated = pipeline_dark_frame_variance(profile)
    assert abs(simulated / measured - 1) < 0.05, (measured, simulated)


def test_read_noise_below_the_rounding_is_floored_at_zero_and_said():
    with pytest.warns(UserWarning, match=r"measured from integer data at 0.22 DN.*cannot be told apart"):
        profile = fit_profile([sensor_info(np.array([[1e-4, 0.05 / SPAN**2]]), "quiet.dng")])
    np.testing.assert_array_equal(np.asarray(profile.noise.read), 0.0)


def test_flag_is_saved_loaded_and_checked(tmp_path):
    profile = fit_profile([sensor_info(np.array([[1e-4, 0.5 / SPAN**2]]), "a.dng")])
    document = profile_to_dict(profile)
    assert document["noise"]["read_excludes_quantisation"] is True
    path = tmp_path / "p.json"
    save_profile(profile, path)
    loaded = load_profile(path)
    assert loaded.noise.read_excludes_quantisation
    np.testing.assert_allclose(np.asarray(loaded.noise.read), np.asarray(profile.noise.read), rtol=1e-6)
    # taking the rounding out twice is not possible
    again = without_quantisation(loaded.noise, np.full(4, BLACK), WHITE)
    np.testing.assert_array_equal(np.asarray(again.read), np.asarray(loaded.noise.read))
    # a profile that does not say keeps its read term as given
    document["noise"].pop("read_excludes_quantisation")
    path.write_text(json.dumps(document))
    assert not load_profile(path).noise.read_excludes_quantisation
    document["noise"]["read_excludes_quantisation"] = "yes"
    path.write_text(json.dumps(document))
    with pytest.raises(ProfileError, match="p.json: noise.read_excludes_quantisation: expected true or false"):
        load_profile(path)


def test_converted_dng_states_the_noise_of_its_integers():
    """The NoiseProfile we write describes the file's integers: read + rounding. Fitting our own
    DNG gives back the profile's read term (the rounding is not taken out twice, nor kept)."""
    from g2r_jax.profile.dng_tags import dng_info_for

    profile = fit_profile([sensor_info(np.array([[1e-4, 0.5 / SPAN**2]]), "a.dng")])
    meta = {"noise_shot": np.asarray(profile.noise.shot[0]), "noise_read": np.asarray(profile.noise.read[0]),
            "neutral": np.array([0.55, 1.0, 0.6]), "iso": 100.0}   # what unprocess reports at ISO 100
    info = dng_info_for(profile, meta, 8, 8, noise=True)
    np.testing.assert_allclose(np.asarray(info.noise_profile)[:, 1], 0.5 / SPAN**2, rtol=1e-5)
    refit = fit_profile([DngInfo(**{**info.__dict__, "path": "ours.dng"})])
    np.testing.assert_allclose(np.asarray(refit.noise.read), np.asarray(profile.noise.read), rtol=1e-4)


def test_illuminant_mean_too_small_fails_validation(tmp_path):
    """A mean of 1e-30 would draw non-positive neutrals file after file: the profile is refused."""
    profile = fit_profile([sensor_info(np.array([[1e-4, 0.5 / SPAN**2]]), "a.dng")])
    document = profile_to_dict(profile)
    document["illuminants"]["means"] = np.full_like(np.asarray(document["illuminants"]["means"]), 1e-30).tolist()
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(document))
    with pytest.raises(ProfileError, match=r"tiny.json: illuminants.means: .*\[0.001, 1000\]"):
        load_profile(path)
