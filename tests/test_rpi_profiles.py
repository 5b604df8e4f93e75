"""The Raspberry Pi camera profiles (profiles/rpi_*.json, built by profiles/build_rpi_profiles.py from
Raspberry Pi's libcamera tuning files): they load and convert with the noise they declare; their DNG
colour model reproduces the tuning's colour correction at its measured temperatures; their
illuminants lie along the measured AWB locus; their levels and shot noise are the tuning's, and the
HQ camera's simulated black frames have the measured black-frame noise."""

from __future__ import annotations

import json
import re
from pathlib import Path

import colour
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax.colour import conversions
from g2r_jax.colour import dng_model
from g2r_jax.illuminants.distributions import sample_neutrals
from g2r_jax.pipeline import unprocess
from g2r_jax.profile.schema import load_profile
from g2r_jax.runtime import x64

PROFILES = {"rpi_hq_imx477": ("imx477", 12), "rpi_camera_module_3_imx708": ("imx708", 10),
            "rpi_global_shutter_imx296": ("imx296", 10)}
TUNING_DIR = Path("../shared/data/cameras/rpi_libcamera/vc4")
needs_tuning = pytest.mark.skipif(not TUNING_DIR.is_dir(), reason="../shared/data (libcamera tuning files) absent")
PROVENANCE_PARTS = ("colour", "levels", "noise", "illuminants", "exposure")
# Measured on the tuning files with the profiles as built (docs/pages/validation/raspberry_pi_cameras.md):
# largest mean CIEDE2000 at a measured temperature 1.70, largest single colour 4.31.
CCM_MEAN_TOLERANCE, CCM_MAX_TOLERANCE = 2.0, 5.0


def tuning(sensor: str) -> dict:
    text = (TUNING_DIR / f"{sensor}.json").read_text()
    document = json.loads(re.sub(r",(\s*[}\]])", r"\1", text))   # libcamera's reader allows trailing commas
    return {name: value for algorithm in document["algorithms"] for name, value in algorithm.items()}


def awb_locus(algorithms: dict) -> np.ndarray:
    return np.asarray(algorithms["rpi.awb"]["ct_curve"], np.float64).reshape(-1, 3)


def locus_neutral(curve: np.ndarray, ct: float) -> np.ndarray:
    """(r, 1, b) at `ct`, linear between the curve's points and beyond its ends (libcamera's Pwl)."""
    upper = int(np.clip(np.searchsorted(curve[:, 0], ct), 1, len(curve) - 1))
    (ct0, r0, b0), (ct1, r1, b1) = curve[upper - 1], curve[upper]
    fraction = (ct - ct0) / (ct1 - ct0)
    return np.array([r0 + fraction * (r1 - r0), 1.0, b0 + fraction * (b1 - b0)])


def flat_mosaic(profile, level: float, iso: float, size: int = 256) -> np.ndarray:
    """A flat grey of linear `level` converted at `iso` with a fixed neutral and exposure."""
    image = jnp.full((size, size, 3), level, jnp.float32)
    convert = jax.jit(lambda iso: unprocess(jax.random.PRNGKey(7), image, profile, transfer="linear", iso=iso,
                                            neutral=jnp.array([0.45, 1.0, 0.6]), exposure_gain=1.0,
                                            effects=False)[0])
    return np.asarray(convert(jnp.float32(iso)), np.float64)


def plane_statistics(mosaic: np.ndarray, profile):
    """Per CFA tile position: (normalised mean x, variance in DN^2)."""
    black, white = float(profile.black_level[0]), float(profile.white_level)
    planes = [mosaic[p // 2::2, p % 2::2] for p in range(4)]
    return [((plane.mean() - black) / (white - black), plane.var()) for plane in planes]


# ----------------------------------------------------------------------------- data-free

@pytest.mark.parametrize("name", PROFILES)
def test_shipped_profile_loads_with_levels_noise_and_provenance(name):
    _, bits = PROFILES[name]
    profile = load_profile(name)
    assert profile.cfa_string == "BGGR"
    assert float(profile.white_level) == 2**bits - 1
    assert 0 < float(profile.black_level[0]) < 0.1 * float(profile.white_level)
    assert np.all(np.asarray(profile.noise.shot) > 0) and np.all(np.asarray(profile.noise.read) > 0)
    assert profile.noise.read_excludes_quantisation   # the read terms come from integer black frames, rounding out
    low, high = np.asarray(profile.noise.iso_range)
    assert low >= 100 and high / low > 10
    assert float(profile.exposure.log2_std) > 0
    parts = dict(profile.info.provenance_parts)
    for part in PROVENANCE_PARTS:
        assert parts.get(part, "").strip(), f"{name}: provenance says nothing about {part}"


@pytest.mark.slow
@pytest.mark.parametrize("name", PROFILES)
def test_flat_grey_at_two_isos_has_the_profiles_variance(name):
    """Mosaic variance = (shot x + read) (white - black)^2 + 1/12 (one rounding), within 5 %
    (the sampling error of a variance over 16384 pixels is 1.1 %)."""
    profile = load_profile(name)
    black, white = float(profile.black_level[0]), float(profile.white_level)
    for iso in np.asarray(profile.noise.iso_range):
        mosaic = flat_mosaic(profile, 0.18, float(iso))
        shot = np.interp(iso, profile.noise.iso, np.asarray(profile.noise.shot)[:, 0])
        read = np.interp(iso, profile.noise.iso, np.asarray(profile.noise.read)[:, 0])
        for x, variance in plane_statistics(mosaic, profile):
            expected = (shot * x + read) * (white - black) ** 2 + 1 / 12
            assert variance == pytest.approx(expected, rel=0.05), (name, iso, x)


# ----------------------------------------------------------------------------- against the tuning files

@pytest.mark.data
@needs_tuning
@pytest.mark.parametrize("name", PROFILES)
def test_levels_and_shot_noise_are_the_tunings(name):
    """black = rpi.black_level >> (16 - bits); shot = reference_slope^2 / 2^(16 - bits) x gain /
    (white - black): the tuning tool fits std = slope sqrt(signal) on 16-bit-scaled raw per unit gain."""
    sensor, bits = PROFILES[name]
    algorithms = tuning(sensor)
    profile = load_profile(name)
    black = algorithms["rpi.black_level"]["black_level"] >> (16 - bits)
    assert np.all(np.asarray(profile.black_level) == black)
    slope = algorithms["rpi.noise"]["reference_slope"]
    iso = np.asarray(profile.noise.iso, np.float64)
    expected = slope**2 / 2 ** (16 - bits) * (iso / 100) / (2**bits - 1 - black)
    np.testing.assert_allclose(np.asarray(profile.noise.shot), np.repeat(expected[:, None], 4, 1), rtol=1e-5)


@pytest.mark.slow
def test_hq_camera_black_frames_have_the_measured_noise():
    """Simulated black frames of the HQ camera (read noise, then the one rounding) have the std
    measured on real black frames: 1.53 DN at analogue gain 1, 11.50 DN at gain 16 (J. Hogan,
    'Pi HQ Cam Sensor Performance', 2020), within 3 %."""
    profile = load_profile("rpi_hq_imx477")
    for iso, measured in ((100.0, 1.53), (1600.0, 11.50)):
        mosaic = flat_mosaic(profile, 0.0, iso)
        assert np.std(mosaic) == pytest.approx(measured, rel=0.03), iso


def _colourchecker_linear_srgb() -> np.ndarray:
    chart = colour.CCS_COLOURCHECKERS["ColorChecker24 - After November 2014"]
    xyz = colour.xyY_to_XYZ(np.array(list(chart.data.values())))
    adapted = colour.adaptation.chromatic_adaptation_VonKries(
        xyz, colour.xy_to_XYZ(conversions.XY_D50), colour.xy_to_XYZ(conversions.XY_D65), transform="Bradford")
    return adapted @ np.asarray(conversions.MATRIX_XYZ_TO_SRGB).T


def _lab(linear_srgb):
    return colour.XYZ_to_Lab(linear_srgb @ np.asarray(conversions.MATRIX_SRGB_TO_XYZ).T, conversions.XY_D65)


def _dng_camera_to_srgb(model, neutral) -> np.ndarray:
    """What a DNG renderer does with a file of AsShotNeutral `neutral` (DNG spec 1.6 ch. 6)."""
    xy, _ = dng_model.camera_neutral_to_xy(jnp.asarray(neutral), model)
    to_d50 = np.asarray(dng_model.matrix_camera_to_XYZ_D50(xy, model))
    d50_to_d65 = np.asarray(conversions.matrix_bradford(jnp.asarray(conversions.XY_D50), jnp.asarray(conversions.XY_D65)))
    return np.asarray(conversions.MATRIX_XYZ_TO_SRGB) @ d50_to_d65 @ to_d50


@pytest.mark.data
@needs_tuning
@pytest.mark.parametrize("name", PROFILES)
def test_colour_model_reproduces_the_tunings_ccms(name):
    """At every temperature the tuning measured a CCM at, libcamera renders camera RGB with
    CCM . diag(1 / neutral), the neutral from its AWB locus. The profile's DNG colour model renders the
    ColorChecker's camera responses within CIEDE2000 mean 2.0 / max 5.0 of that; at the profile's
    calibration illuminants (2850, 5500, 7500 K) it is the tuning's interpolated CCM exactly."""
    sensor, _ = PROFILES[name]
    algorithms = tuning(sensor)
    curve = awb_locus(algorithms)
    neutral_at = lambda ct: locus_neutral(curve, ct)
    entries = algorithms["rpi.ccm"]["ccms"]
    cts = np.array([e["ct"] for e in entries], np.float64)
    ccms = np.array([np.reshape(e["ccm"], (3, 3)) for e in entries])
    reference = _colourchecker_linear_srgb()
    with x64.enable_x64():
        model = load_profile(name, dtype=np.float64).colour
        for ct, ccm in zip(cts, ccms):
            neutral = neutral_at(ct)
            camera = reference @ np.linalg.inv(ccm).T * neutral
            rendered = camera @ _dng_camera_to_srgb(model, neutral).T
            difference = colour.delta_E(_lab(reference), _lab(rendered), method="CIE 2000")
            assert difference.mean() <= CCM_MEAN_TOLERANCE and difference.max() <= CCM_MAX_TOLERANCE, (ct, difference)
        for cct in (2850.0, 5500.0, 7500.0):
            clamped = np.clip(cct, cts[0], cts[-1])
            upper = int(np.clip(np.searchsorted(cts, clamped), 1, len(cts) - 1))
            fraction = (clamped - cts[upper - 1]) / (cts[upper] - cts[upper - 1])
            ccm = fraction * ccms[upper] + (1 - fraction) * ccms[upper - 1]
            neutral = neutral_at(cct)
            np.testing.assert_allclose(_dng_camera_to_srgb(model, neutral), ccm / neutral, atol=1e-6)


@pytest.mark.data
@needs_tuning
@pytest.mark.parametrize("name", PROFILES)
def test_illuminant_samples_lie_along_the_measured_awb_locus(name):
    """Sampled neutrals sit across the locus within libcamera's transverse AWB band (-neg, +pos)
    (at least 88 %: the band's uniform std as a Gaussian puts 92 % inside), none beyond twice the band,
    and along it over the auto-AWB range (5th and 95th percentile of the nearest locus CT)."""
    sensor, _ = PROFILES[name]
    algorithms = tuning(sensor)
    awb = algorithms["rpi.awb"]
    curve = awb_locus(algorithms)
    low, high = awb["modes"]["auto"]["lo"], awb["modes"]["auto"]["hi"]
    profile = load_profile(name)
    points = np.asarray(sample_neutrals(jax.random.PRNGKey(0), profile.illuminants, 4000), np.float64)[:, [0, 2]]
    cts = np.geomspace(low, high, 4000)
    extend = lambda column: np.interp(cts, curve[:, 0], curve[:, column], left=np.nan, right=np.nan)
    locus = np.stack([extend(1), extend(2)], 1)
    keep = np.all(np.isfinite(locus), 1)   # inside the measured curve (the profile extends it linearly)
    locus, cts = locus[keep], cts[keep]
    nearest = np.argmin(np.linalg.norm(points[:, None] - locus[None], axis=-1), axis=1)
    tangent = np.gradient(locus, axis=0)[nearest]
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], 1) / np.linalg.norm(tangent, axis=1, keepdims=True)
    offset = np.sum((points - locus[nearest]) * normal, axis=1)
    inside = (offset >= -awb["transverse_neg"]) & (offset <= awb["transverse_pos"])
    band = awb["transverse_neg"] + awb["transverse_pos"]
    assert inside.mean() >= 0.88
    assert np.max(np.abs(offset)) <= 2 * band
    sampled_ct = cts[nearest]
    assert np.percentile(sampled_ct, 5) <= 1.2 * max(low, curve[0, 0])
    assert np.percentile(sampled_ct, 95) >= min(high, curve[-1, 0]) / 1.2
