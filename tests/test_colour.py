"""g2r_jax.colour against colour-science's own implementations."""

import colour
import jax
import numpy as np
import pytest

from g2r_jax.colour import conversions as gc
from g2r_jax.runtime.x64 import enable_x64


@pytest.fixture(autouse=True)
def x64():
    with enable_x64():
        yield


def test_srgb_transfer_matches_colour_science():
    values = np.linspace(-0.01, 1.2, 1001)
    expected = colour.models.eotf_sRGB(np.clip(values, 0, None))
    np.testing.assert_allclose(gc.srgb_to_linear(np.clip(values, 0, None)), expected, atol=1e-12)
    np.testing.assert_allclose(gc.linear_to_srgb(expected), np.clip(values, 0, None), atol=1e-12)


def test_decode_lut_is_exact_at_every_code():
    lut = gc.srgb_decode_lut("srgb", np.float64)
    np.testing.assert_allclose(lut, colour.models.eotf_sRGB(np.arange(256) / 255), atol=1e-12)
    np.testing.assert_allclose(gc.srgb_decode_lut("gamma2.2", np.float64), (np.arange(256) / 255) ** 2.2, atol=1e-12)


def test_cct_matches_robertson_1968_of_colour_science():
    rng = np.random.default_rng(1)
    cct = rng.uniform(1700, 20000, 300)
    xy = colour.temperature.CCT_to_xy_Kang2002(cct) + rng.normal(0, 0.004, (300, 2))
    expected = colour.temperature.uv_to_CCT_Robertson1968(colour.UCS_to_uv(colour.XYZ_to_UCS(colour.xy_to_XYZ(xy))))[..., 0]
    np.testing.assert_allclose(gc.xy_to_CCT(xy), expected, rtol=1e-9)


def test_bradford_matches_colour_science():
    rng = np.random.default_rng(2)
    for _ in range(20):
        source, target = rng.uniform(0.28, 0.45, 2), rng.uniform(0.28, 0.45, 2)
        expected = colour.adaptation.matrix_chromatic_adaptation_VonKries(
            colour.xy_to_XYZ(source), colour.xy_to_XYZ(target), "Bradford")
        np.testing.assert_allclose(gc.matrix_bradford(source, target), expected, atol=1e-12)


def test_xy_XYZ_round_trip():
    xy = np.array([[0.3127, 0.329], [0.4476, 0.4074]])
    np.testing.assert_allclose(gc.XYZ_to_xy(gc.xy_to_XYZ(xy)), xy, atol=1e-15)
    np.testing.assert_allclose(gc.xy_to_XYZ(xy), colour.xy_to_XYZ(xy) / colour.xy_to_XYZ(xy)[:, 1:2], atol=1e-15)
