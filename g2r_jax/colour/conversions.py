"""Colour science in JAX: transfer curves, RGB<->XYZ, xy/uv, CCT and chromatic adaptation.

Every constant that colour-science holds (sRGB primaries, CIE whitepoints, the Bradford cone
matrix, Robertson's isotemperature lines) is copied from colour-science by a build step
(`build_constants`, into `cie_constants`; a test checks the copies still equal the library's),
never retyped, so that converting images does not import colour-science and its plotting stack. All functions are pure and work on arrays of any leading shape (last axis = channels),
in whatever float dtype they are given.
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.colour import cie_constants

XY_D50 = np.asarray(cie_constants.XY_D50, dtype=np.float64)
XY_D65 = np.asarray(cie_constants.XY_D65, dtype=np.float64)
XY_A = np.asarray(cie_constants.XY_A, dtype=np.float64)

MATRIX_SRGB_TO_XYZ = np.asarray(cie_constants.MATRIX_SRGB_TO_XYZ, np.float64)
MATRIX_XYZ_TO_SRGB = np.linalg.inv(MATRIX_SRGB_TO_XYZ)
MATRIX_BRADFORD = np.asarray(cie_constants.MATRIX_BRADFORD, dtype=np.float64)

# IEC 61966-2-1:1999 sRGB electro-optical transfer function constants.
_SRGB_THRESHOLD = 0.04045
_SRGB_LINEAR_SLOPE = 12.92
_SRGB_OFFSET = 0.055
_SRGB_EXPONENT = 2.4

_ROBERTSON = np.asarray(cie_constants.ROBERTSON_1968, dtype=np.float64)
_SDK_TINT_SCALE = -3000.0   # Adobe DNG SDK dng_temperature.cpp kTintScale


def import_colour_science():
    """colour-science, imported on first use (fit-time functions only): its import pulls in its
    plotting package and matplotlib, about a second that converting images does not pay."""
    with warnings.catch_warnings():   # it warns on import when matplotlib (plotting only) is absent
        warnings.filterwarnings("ignore", message=".*Matplotlib.*")
        import colour
    return colour


def _power(base, exponent: float):
    """base ** exponent for base >= 0, as exp(exponent * ln base). XLA's CPU `pow` runs per element
    (scalar); exp and log are emitted as vectorised polynomials. Measured on 12-MP float32 frames:
    the sRGB decode 176 -> 54 ms per frame on 2 cores, relative error 7e-7 against float64 (pow's:
    3e-7), far below the 14-bit output's 6e-5."""
    return jnp.exp(exponent * jnp.log(base))


def srgb_to_linear(encoded):
    """sRGB EOTF (IEC 61966-2-1:1999, eq. for R'G'B' -> RGB): exact piecewise curve."""
    encoded = jnp.asarray(encoded)
    power = _power((jnp.maximum(encoded, _SRGB_THRESHOLD) + _SRGB_OFFSET) / (1 + _SRGB_OFFSET), _SRGB_EXPONENT)
    return jnp.where(encoded <= _SRGB_THRESHOLD, encoded / _SRGB_LINEAR_SLOPE, power)


def linear_to_srgb(linear):
    """Inverse sRGB EOTF (IEC 61966-2-1:1999)."""
    linear = jnp.asarray(linear)
    threshold = _SRGB_THRESHOLD / _SRGB_LINEAR_SLOPE
    power = (1 + _SRGB_OFFSET) * _power(jnp.maximum(linear, threshold), 1 / _SRGB_EXPONENT) - _SRGB_OFFSET
    return jnp.where(linear <= threshold, linear * _SRGB_LINEAR_SLOPE, power)


def gamma_to_linear(encoded, gamma: float = 2.2):
    """Plain power-law decoding, the published Graphics2RAW code's choice (gamma 2.2)."""
    return _power(jnp.maximum(jnp.asarray(encoded), 0.0), gamma)


def decode_to_linear(encoded, transfer: str):
    """Decode display values with `transfer` in {'srgb', 'gamma2.2', 'linear'}."""
    if transfer == "srgb":
        return srgb_to_linear(encoded)
    if transfer == "gamma2.2":
        return gamma_to_linear(encoded, 2.2)
    if transfer == "linear":
        return jnp.asarray(encoded)
    raise ValueError(f"unknown transfer {transfer!r}; expected 'srgb', 'gamma2.2' or 'linear'")


def srgb_decode_lut(transfer: str = "srgb", dtype=np.float32) -> np.ndarray:
    """256-entry look-up table decoding 8-bit codes with `transfer` (computed in float64, then
    rounded to `dtype`)."""
    from g2r_jax.runtime.x64 import enable_x64

    codes = np.arange(256, dtype=np.float64) / 255.0
    with jax.ensure_compile_time_eval(), enable_x64():
        return np.asarray(decode_to_linear(codes, transfer), dtype=dtype)


def xy_to_XYZ(xy):
    """CIE xy chromaticity -> XYZ with Y = 1 (CIE 15:2004, eq. 7.3 inverted)."""
    xy = jnp.asarray(xy)
    x, y = xy[..., 0], xy[..., 1]
    return jnp.stack([x / y, jnp.ones_like(x), (1 - x - y) / y], axis=-1)


def XYZ_to_xy(XYZ):
    """CIE XYZ -> xy chromaticity (CIE 15:2004, eq. 7.3)."""
    XYZ = jnp.asarray(XYZ)
    return XYZ[..., :2] / jnp.sum(XYZ, axis=-1, keepdims=True)


def XYZ_to_uv(XYZ):
    """CIE XYZ -> CIE 1960 UCS uv (u = 4X / (X + 15Y + 3Z), v = 6Y / (X + 15Y + 3Z))."""
    XYZ = jnp.asarray(XYZ)
    denominator = XYZ[..., 0] + 15 * XYZ[..., 1] + 3 * XYZ[..., 2]
    return jnp.stack([4 * XYZ[..., 0] / denominator, 6 * XYZ[..., 1] / denominator], axis=-1)


def xy_to_CCT(xy):
    """Correlated colour temperature of xy by Robertson (1968), as the Adobe DNG SDK does.

    Wyszecki & Stiles, *Color Science* (2000), pp. 227-228: the uv point is located between
    two of the 31 isotemperature lines (table from colour-science) and the reciprocal
    temperature interpolated by the perpendicular distances. Matches
    `colour.temperature.uv_to_CCT_Robertson1968` including its out-of-table behaviour.
    """
    return xy_to_CCT_tint(xy)[0]


def xy_to_CCT_tint(xy):
    """(CCT, tint) of xy as the Adobe DNG SDK's `dng_temperature` computes them (SDK 1.6,
    dng_temperature.cpp): the Robertson CCT of `xy_to_CCT`, and the tint, the signed distance in
    CIE 1960 uv from the locus point along the interpolated isotemperature line, times -3000
    (the SDK's kTintScale).
    """
    uv = XYZ_to_uv(xy_to_XYZ(xy))
    table = jnp.asarray(_ROBERTSON, dtype=uv.dtype)
    mired, u_line, v_line, slope = table[:, 0], table[:, 1], table[:, 2], table[:, 3]
    length = jnp.sqrt(1.0 + slope**2)
    du, dv = 1.0 / length, slope / length
    u = uv[..., 0:1]
    v = uv[..., 1:2]
    distance = -(u - u_line[1:]) * dv[1:] + (v - v_line[1:]) * du[1:]
    crossed = distance <= 0
    n_lines = table.shape[0] - 1
    index = jnp.where(jnp.any(crossed, axis=-1), jnp.argmax(crossed, axis=-1) + 1, n_lines)
    d_current = -jnp.minimum(jnp.take_along_axis(distance, (index - 1)[..., None], -1)[..., 0], 0.0)
    d_previous = jnp.take_along_axis(distance, jnp.maximum(index - 2, 0)[..., None], -1)[..., 0]
    fraction = jnp.where(index == 1, 0.0, d_current / (d_previous + d_current))
    cct = 1e6 / (mired[index - 1] * fraction + mired[index] * (1 - fraction))
    locus_u = u_line[index - 1] * fraction + u_line[index] * (1 - fraction)
    locus_v = v_line[index - 1] * fraction + v_line[index] * (1 - fraction)
    direction_u = du[index] * (1 - fraction) + du[index - 1] * fraction
    direction_v = dv[index] * (1 - fraction) + dv[index - 1] * fraction
    norm = jnp.sqrt(direction_u**2 + direction_v**2)
    along = ((uv[..., 0] - locus_u) * direction_u + (uv[..., 1] - locus_v) * direction_v) / norm
    return cct, along * _SDK_TINT_SCALE


def matrix_bradford(xy_source, xy_target):
    """Bradford chromatic adaptation matrix from white xy_source to white xy_target.

    von Kries scaling in the Bradford cone space (Lam 1985; cone matrix from colour-science):
    M = B^-1 diag(B w_t / B w_s) B, with whites at Y = 1 as the DNG SDK and colour-science use.
    """
    bradford = jnp.asarray(MATRIX_BRADFORD, dtype=jnp.result_type(xy_source, float))
    cone_source = xy_to_XYZ(xy_source) @ bradford.T
    cone_target = xy_to_XYZ(xy_target) @ bradford.T
    gains = cone_target / cone_source
    return jnp.linalg.inv(bradford) @ (gains[..., :, None] * bradford)


def CCT_to_xy(cct) -> np.ndarray:
    """xy of a white at `cct` (numpy; used at fit time only), without a kink between lamp and daylight.

    The Planckian locus (Kang et al. 2002 approximation) below 4000 K, the CIE daylight locus
    (CIE 15:2004 eq. 3.3) above 5000 K, and a smoothstep blend of the two in between; both
    curves from colour-science. Standard Light A lies on the first, D65 on the second.
    """
    colour = import_colour_science()
    cct = np.atleast_1d(np.asarray(cct, dtype=np.float64))
    planckian = np.stack([colour.temperature.CCT_to_xy_Kang2002(t) for t in cct])
    daylight = np.stack([colour.temperature.CCT_to_xy_CIE_D(np.clip(t, 4000, 25000)) for t in cct])
    blend = np.clip((cct - 4000.0) / 1000.0, 0.0, 1.0)
    blend = (blend * blend * (3 - 2 * blend))[:, None]
    return (1 - blend) * planckian + blend * daylight
