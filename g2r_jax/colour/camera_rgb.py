"""sRGB -> the camera's raw RGB: the colour-space transform of the DNG colour model and the
mosaic that keeps one channel per pixel (Graphics2RAW, Seo et al. ICCV 2023, Sec. 3; stage names
after Brooks et al., "Unprocessing Images for Learned Raw Denoising", CVPR 2019)."""

from __future__ import annotations

import jax.numpy as jnp

from g2r_jax.colour import conversions as _colour
from g2r_jax.colour import dng_model as _dng
from g2r_jax import sensor as _sensor


HIGHLIGHT_INFLECTION = 0.9  # Brooks et al. 2019, safe_invert_gains
_STANDARD_LIGHT_A_PUBLISHED = 2500.0  # the published code's value (the DNG SDK uses 2850 K)


def matrix_srgb_to_white_balanced_camera(xy, neutral, colour_model):
    """Linear sRGB -> white-balanced camera RGB at white xy: sRGB white maps to (1, 1, 1).

    inverse(Bradford(D50 -> D65) . CameraToXYZ_D50(xy)) . sRGB_to_XYZ gives camera RGB, whose
    white is proportional to the camera neutral; dividing each row by its white response is
    exactly removing that neutral (white balance).
    """
    srgb_to_xyz = jnp.asarray(_colour.MATRIX_SRGB_TO_XYZ, neutral.dtype)
    srgb_to_camera = _dng.matrix_XYZ_D65_to_camera(xy, colour_model) @ srgb_to_xyz
    return srgb_to_camera / jnp.sum(srgb_to_camera, axis=1, keepdims=True)


def matrix_srgb_to_white_balanced_camera_published(cct, colour_model):
    """The published code's CST: row-normalised ColorMatrices, 2500 K for Standard Light A,
    interpolation in mired without clamping, applied to D65-relative XYZ (no adaptation)."""
    low_cct = jnp.where(colour_model.calibration_cct[0] == 2850.0, _STANDARD_LIGHT_A_PUBLISHED,
                        colour_model.calibration_cct[0])
    high_cct = colour_model.calibration_cct[-1]
    span = jnp.where(low_cct == high_cct, 1.0, 1.0 / low_cct - 1.0 / high_cct)
    weight = jnp.where(low_cct == high_cct, 1.0, (1.0 / cct - 1.0 / high_cct) / span)
    normalised = colour_model.color_matrix / jnp.sum(colour_model.color_matrix, axis=2, keepdims=True)
    xyz_to_camera = weight * normalised[0] + (1 - weight) * normalised[-1]
    return xyz_to_camera @ jnp.asarray(_colour.MATRIX_SRGB_TO_XYZ, cct.dtype)


def dot_channels(rgb, weights):
    """sum_c rgb[..., c] * weights[c], written out: an einsum over 3 channels becomes a dot
    that XLA runs on a materialised copy of its operands, this fuses with its neighbours."""
    return rgb[..., 0] * weights[0] + rgb[..., 1] * weights[1] + rgb[..., 2] * weights[2]


def resolve_highlight_safe(highlight_safe: bool | None, recipe: str) -> bool:
    """`highlight_safe` as given, or by default only for the published recipe (README "Highlights")."""
    return recipe == "published" if highlight_safe is None else bool(highlight_safe)


def mosaic_camera_rgb(linear, srgb_to_wb_camera, gains, cfa_pattern, highlight_safe: bool):
    """Mosaicked un-white-balanced camera RGB (H, W) from linear sRGB (H, W, 3), computing only
    the channel each pixel keeps (the matrix row and gain of its tile position).

    Un-white-balance multiplies by the neutral; with `highlight_safe` the gain is eased to 1
    for near-white pixels (Brooks et al. 2019, safe_invert_gains) so highlights stay neutral.
    """
    shape = linear.shape[:2]
    rows = srgb_to_wb_camera[cfa_pattern]                        # (4, 3) one row per tile position
    kept = dot_channels(linear, [_sensor.per_position(rows[:, c], shape) for c in range(3)])
    gain = _sensor.per_position(gains[cfa_pattern], shape)
    if not highlight_safe:
        return kept * gain
    gray = dot_channels(linear, jnp.mean(srgb_to_wb_camera, axis=0))
    mask = (jnp.maximum(gray - HIGHLIGHT_INFLECTION, 0.0) / (1.0 - HIGHLIGHT_INFLECTION)) ** 2
    return kept * jnp.maximum(mask + (1.0 - mask) * gain, gain)
