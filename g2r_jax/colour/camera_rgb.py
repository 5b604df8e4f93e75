"""sRGB -> the camera's raw RGB: the colour-space transform of the DNG colour model and the
mosaic that keeps one channel per pixel (Graphics2RAW, Seo et al. ICCV 2023, Sec. 3; stage names
after Brooks et al., "Unprocessing Images for Learned Raw Denoising", CVPR 2019)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.colour import conversions as _colour
from g2r_jax.colour import dng_model as _dng
from g2r_jax import sensor as _sensor


HIGHLIGHT_INFLECTION = 0.9  # Brooks et al. 2019, safe_invert_gains

# The released Graphics2RAW code, github.com/SamsungLabs/graphics2raw at 62041b0 ("released"):
# its CCTs of Standard Light A and D65 (pipeline/cct_utils.py raw_rgb_to_xyz, interpolate_cst;
# the DNG values are 2850 K and 6500 K), the start, tolerance and iteration cap of its CCT
# search (raw_rgb_to_cct), and its XYZ -> sRGB matrix (utils/img_utils.py get_xyz_to_srgb_mat:
# Lindbloom's D65 sRGB matrix to 7 digits).
_PUBLISHED_CCT_A = 2500.0
_PUBLISHED_CCT_D65 = 6500.0
_PUBLISHED_CCT_START_XYZ = (0.3, 0.3, 0.3)
_PUBLISHED_CCT_TOLERANCE = 1e-4
_PUBLISHED_CCT_MAX_ITERATIONS = 100   # the released loop allows 10000; it settles in about 5
_PUBLISHED_MATRIX_XYZ_TO_SRGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                                          [-0.9692660, 1.8760108, 0.0415560],
                                          [0.0556434, -0.2040259, 1.0572252]])


def matrix_srgb_to_white_balanced_camera(xy, neutral, colour_model):
    """Linear sRGB -> white-balanced camera RGB at white xy: sRGB white maps to (1, 1, 1).

    inverse(Bradford(D50 -> D65) . CameraToXYZ_D50(xy)) . sRGB_to_XYZ gives camera RGB, whose
    white is proportional to the camera neutral; dividing each row by its white response is
    exactly removing that neutral (white balance).
    """
    srgb_to_xyz = jnp.asarray(_colour.MATRIX_SRGB_TO_XYZ, neutral.dtype)
    srgb_to_camera = _dng.matrix_XYZ_D65_to_camera(xy, colour_model) @ srgb_to_xyz
    return srgb_to_camera / jnp.sum(srgb_to_camera, axis=1, keepdims=True)


def _rows_summing_to_one(matrix):
    """Each row divided by its sum: the matrix then maps (1, 1, 1) to (1, 1, 1)."""
    return matrix / jnp.sum(matrix, axis=-1, keepdims=True)


# Linear sRGB -> "XYZ" of the released code: the inverse of its row-normalised XYZ -> sRGB matrix
# (invert_synthia_graphics2raw.py line 148), which sends sRGB white to (1, 1, 1), not to D65.
MATRIX_SRGB_TO_XYZ_PUBLISHED = np.linalg.inv(
    _PUBLISHED_MATRIX_XYZ_TO_SRGB / np.sum(_PUBLISHED_MATRIX_XYZ_TO_SRGB, axis=1, keepdims=True))


def _published_calibration_ccts(colour_model):
    """(low, high) calibration CCTs as the released code takes them: Standard Light A at 2500 K,
    D65 at 6500 K; other illuminants (which the released code does not handle) at their own CCT."""
    ccts = colour_model.calibration_cct
    low = jnp.where(ccts[0] == _dng.CALIBRATION_ILLUMINANT_CCT[17], _PUBLISHED_CCT_A, ccts[0])
    high = jnp.where(ccts[-1] == _dng.CALIBRATION_ILLUMINANT_CCT[21], _PUBLISHED_CCT_D65, ccts[-1])
    return low, high


def _published_low_weight(cct, low, high):
    """Weight of the low-CCT matrix, linear in inverse CCT, not clamped (cct_utils.py); 1 for a
    one-matrix model."""
    same = low == high
    return jnp.where(same, 1.0, (1.0 / cct - 1.0 / high) / jnp.where(same, 1.0, 1.0 / low - 1.0 / high))


def published_neutral_cct(neutral, colour_model):
    """The CCT of a camera neutral as the released code finds it (pipeline/cct_utils.py
    raw_rgb_to_cct): from XYZ = (0.3, 0.3, 0.3), repeat T = Robertson(XYZ),
    XYZ = inverse(w M_A' + (1 - w) M_D65') neutral, with M' the ROW-NORMALISED ColorMatrices and w
    the unclamped 2500 K / 6500 K weight, until XYZ moves by less than 1e-4; returns the last T.

    The row normalisation moves the neutral's XYZ, hence this CCT, far from the DNG white point
    (Canon600D: the neutral of a 2500 K white reads about 4600 K). Robertson (1968) as in
    `xy_to_CCT`; where the released table lookup fails (below 1667 K) it returns -1, we extrapolate.
    """
    dtype = neutral.dtype
    matrices = _rows_summing_to_one(colour_model.color_matrix.astype(dtype))
    low, high = _published_calibration_ccts(colour_model)

    def step(state):
        xyz, _, _, iteration = state
        cct = _colour.xy_to_CCT(_colour.XYZ_to_xy(xyz))
        weight = _published_low_weight(cct, low, high)
        new_xyz = jnp.linalg.solve(weight * matrices[0] + (1 - weight) * matrices[-1], neutral)
        return new_xyz, cct, jnp.linalg.norm(new_xyz - xyz), iteration + 1

    moving = lambda state: (state[2] > _PUBLISHED_CCT_TOLERANCE) & (state[3] < _PUBLISHED_CCT_MAX_ITERATIONS)
    start = (jnp.asarray(_PUBLISHED_CCT_START_XYZ, dtype), jnp.asarray(_PUBLISHED_CCT_D65, dtype),
             jnp.asarray(jnp.inf, dtype), jnp.asarray(0, jnp.int32))
    return jax.lax.while_loop(moving, step, start)[1]


def matrix_srgb_to_white_balanced_camera_published(neutral, colour_model):
    """Linear sRGB -> white-balanced camera RGB as the released Graphics2RAW code computes it
    (github.com/SamsungLabs/graphics2raw at 62041b0: data_generation/invert_synthia_graphics2raw.py
    lines 145-151, utils/img_utils.py get_cst_matrix and get_xyz_to_srgb_mat, pipeline/cct_utils.py):

        M_XYZ->cam = rows_to_one(w M_A' + (1 - w) M_D65'),  M' = rows_to_one(ColorMatrix),
        w = clip((1/T - 1/6500) / (1/2500 - 1/6500), 0, 1),  T = `published_neutral_cct`(neutral),
        M_sRGB->XYZ = inverse(rows_to_one(M_XYZ->sRGB)),

    returned as M_XYZ->cam M_sRGB->XYZ. Both factors map (1, 1, 1) to (1, 1, 1), so sRGB white
    is camera white (1, 1, 1) before the neutral's gains (the white-point change is this row
    scaling, no Bradford adaptation). The released interpolate_cst clamps g < 0 to 0 and h = 1 - g
    into [0, 1]; past 6500 K its g > 1 remains, but the final row normalisation removes that
    scale, which is the clamp applied here. Its [0, 1] clip after each matrix is not applied.
    """
    low, high = _published_calibration_ccts(colour_model)
    weight = jnp.clip(_published_low_weight(published_neutral_cct(neutral, colour_model), low, high), 0.0, 1.0)
    matrices = _rows_summing_to_one(colour_model.color_matrix.astype(neutral.dtype))
    xyz_to_camera = _rows_summing_to_one(weight * matrices[0] + (1 - weight) * matrices[-1])
    return xyz_to_camera @ jnp.asarray(MATRIX_SRGB_TO_XYZ_PUBLISHED, neutral.dtype)


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
