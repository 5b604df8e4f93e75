"""recipe='published' against the released Graphics2RAW code's colour math
(github.com/SamsungLabs/graphics2raw at 62041b0: data_generation/invert_synthia_graphics2raw.py,
utils/img_utils.py get_cst_matrix / get_xyz_to_srgb_mat, pipeline/cct_utils.py), derived here
by hand in numpy from the shipped Canon600D profile's ColorMatrices (the NUS camera's DNG tags,
the same values the released code reads from its NUS_CST_mats.p)."""

import json

import colour
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax import load_profile, unprocess
from g2r_jax.colour.camera_rgb import matrix_srgb_to_white_balanced_camera_published, published_neutral_cct

PROFILE = "profiles/Canon600D.json"
# Lindbloom's XYZ -> sRGB (D65), the released get_xyz_to_srgb_mat before its row normalisation
XYZ_TO_SRGB_LINDBLOOM = np.array([[3.2404542, -1.5371385, -0.4985314],
                                  [-0.9692660, 1.8760108, 0.0415560],
                                  [0.0556434, -0.2040259, 1.0572252]])
# camera neutrals (r/g, 1, b/g): the Canon600D's daylight-to-tungsten range, a bluish shade, and two
# far outside it that put the released CCT below 2500 K and above 6500 K (both clamps exercised)
NEUTRALS = [(0.46, 1.0, 0.606), (0.821, 1.0, 0.324), (0.37, 1.0, 0.79), (2.0, 1.0, 0.1), (0.3, 1.0, 0.95)]


def rows_to_one(matrix):
    return matrix / matrix.sum(axis=-1, keepdims=True)


def canon600d_normalised_matrices():
    """(A, D65) ColorMatrices of the shipped profile's JSON, each row scaled to sum 1."""
    tags = json.loads(open(PROFILE).read())["colour"]
    by_code = dict(zip(tags["calibration_illuminants"], tags["color_matrices"]))
    return rows_to_one(np.asarray(by_code[17], np.float64)), rows_to_one(np.asarray(by_code[21], np.float64))


def d65_weight(cct):
    """The released weight g of the D65 matrix: linear in 1/CCT between 2500 K (0) and 6500 K (1)."""
    return (1 / cct - 1 / 2500) / (1 / 6500 - 1 / 2500)


def released_cct(neutral, matrix_a, matrix_d65):
    """raw_rgb_to_cct: fixed point of CCT(XYZ) and XYZ = inverse(interpolated matrix) neutral from
    XYZ = 0.3 each, weight not clamped, stopping when XYZ moves by under 1e-4."""
    xyz, moved, cct = np.full(3, 0.3), np.inf, None
    while moved > 1e-4:
        cct = colour.temperature.uv_to_CCT_Robertson1968(colour.xy_to_UCS_uv(colour.XYZ_to_xy(xyz)))[0]
        g = d65_weight(cct)
        new = np.linalg.solve(g * matrix_d65 + (1 - g) * matrix_a, np.asarray(neutral, np.float64))
        moved, xyz = np.linalg.norm(new - xyz), new
    return cct


def released_srgb_to_white_balanced_camera(neutral):
    """inverse(get_cst_matrix) @ inverse(get_xyz_to_srgb_mat), both by their definitions."""
    matrix_a, matrix_d65 = canon600d_normalised_matrices()
    g = d65_weight(released_cct(neutral, matrix_a, matrix_d65))
    g, h = max(g, 0.0), min(max(1 - g, 0.0), 1.0)       # interpolate_cst's clamps, as written
    xyz_to_camera = rows_to_one(g * matrix_d65 + h * matrix_a)
    return xyz_to_camera @ np.linalg.inv(rows_to_one(XYZ_TO_SRGB_LINDBLOOM))


@pytest.fixture(scope="module")
def profile():
    return load_profile(PROFILE)


@pytest.fixture(scope="module")
def ours(profile):
    """(CCTs, transforms) of `NEUTRALS` by g2r_jax, in one compiled call."""
    neutrals = jnp.asarray(NEUTRALS, jnp.float32)
    both = jax.jit(jax.vmap(lambda n: (published_neutral_cct(n, profile.colour),
                                       matrix_srgb_to_white_balanced_camera_published(n, profile.colour))))
    return tuple(np.asarray(a, np.float64) for a in both(neutrals))


@pytest.mark.parametrize("k", range(len(NEUTRALS)))
def test_published_cct_is_the_released_fixed_point(ours, k):
    matrix_a, matrix_d65 = canon600d_normalised_matrices()
    assert ours[0][k] == pytest.approx(released_cct(NEUTRALS[k], matrix_a, matrix_d65), rel=1e-4)


@pytest.mark.parametrize("k", range(len(NEUTRALS)))
def test_published_transform_is_the_released_one(ours, k):
    np.testing.assert_allclose(ours[1][k], released_srgb_to_white_balanced_camera(NEUTRALS[k]), atol=2e-5)


def test_published_transform_keeps_srgb_white_white(ours):
    """sRGB (1, 1, 1) -> camera (1, 1, 1) before the gains: the released XYZ of sRGB white is
    (1, 1, 1), so no cast is left for the neutral's gains to be confused with."""
    np.testing.assert_allclose(ours[1].sum(axis=2), 1.0, atol=1e-5)


@pytest.mark.slow
def test_published_recipe_records_white_at_the_neutral(profile):
    """A grey input becomes a raw pixel in the ratio of the neutral (AsShotNeutral), as the released
    code's sRGB -> XYZ -> camera chain sends white to (1, 1, 1) before the gains."""
    neutral = np.array([0.46, 1.0, 0.606])
    grey = jnp.full((4, 4, 3), 128, jnp.uint8)
    mosaic, _ = unprocess(jax.random.PRNGKey(0), grey, profile, neutral=jnp.asarray(neutral, jnp.float32),
                          exposure_gain=1.0, noise=False, effects=False, quantize=False, recipe="published")
    black = np.asarray(profile.black_level, np.float64).reshape(-1)
    black = np.broadcast_to(black if black.size == 4 else black[:1], (4,)).reshape(2, 2)
    cfa = np.asarray(profile.cfa_pattern).reshape(2, 2)
    mosaic = np.asarray(mosaic, np.float64)
    recorded = np.zeros(3)
    for i in range(2):
        for j in range(2):
            recorded[cfa[i, j]] = mosaic[i::2, j::2].mean() - black[i, j]
    np.testing.assert_allclose(recorded / recorded[1], neutral, rtol=1e-4)
