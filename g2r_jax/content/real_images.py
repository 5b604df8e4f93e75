"""Images into the camera's white-balanced RGB, the space of the content statistics.

Real camera-RGB images are divided by their as-shot neutral (white balance). CG images in linear
sRGB go through the profile's sRGB -> white-balanced camera transform at a white
(`colour.camera_rgb.matrix_srgb_to_white_balanced_camera`, the exact inverse of a DNG renderer's
colour transform, DNG spec 1.6 chapter 6), whose white point comes from the neutral by the DNG
fixed point (`colour.dng_model.camera_neutral_to_xy`). Going the other way, real images reach
linear sRGB by the inverse of that matrix (what a DNG renderer does before its tone curve).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.colour.camera_rgb import matrix_srgb_to_white_balanced_camera
from g2r_jax.colour.dng_model import camera_neutral_to_xy

_CHUNK = 64   # neutrals per compiled call (one fixed shape whatever the folder's size)


@eqx.filter_jit
def _srgb_to_camera(neutrals, colour_model):
    def one(neutral):
        xy, _ = camera_neutral_to_xy(neutral, colour_model, throw=False)
        return matrix_srgb_to_white_balanced_camera(xy, neutral, colour_model)

    return jax.vmap(one)(neutrals)


def _checked_neutrals(neutrals) -> np.ndarray:
    neutrals = np.asarray(neutrals, np.float64)
    if neutrals.ndim != 2 or neutrals.shape[1] != 3 or not np.all(np.isfinite(neutrals)) or np.any(neutrals <= 0):
        raise ValueError(f"neutrals must be (N, 3), finite and positive, got shape {neutrals.shape}")
    return neutrals / neutrals[:, 1:2]


def srgb_to_camera_matrices(neutrals, colour_model) -> np.ndarray:
    """(N, 3) camera neutrals -> (N, 3, 3) linear sRGB -> white-balanced camera RGB matrices."""
    neutrals = _checked_neutrals(neutrals).astype(np.float32)
    out = []
    for start in range(0, len(neutrals), _CHUNK):
        part = neutrals[start:start + _CHUNK]
        padded = np.concatenate([part, np.repeat(part[:1], _CHUNK - len(part), 0)])
        out.append(np.asarray(_srgb_to_camera(jnp.asarray(padded), colour_model), np.float64)[: len(part)])
    return np.concatenate(out) if out else np.zeros((0, 3, 3))


def white_balanced_camera_rgb(images, neutrals) -> np.ndarray:
    """Real camera-RGB images (N, H, W, 3) divided by their neutrals (N, 3): white-balanced camera
    RGB (float32; zeroed saturated pixels stay 0)."""
    images = np.asarray(images, np.float64)
    neutrals = _checked_neutrals(neutrals)
    if images.ndim != 4 or images.shape[-1] != 3 or len(images) != len(neutrals):
        raise ValueError(f"expected images (N, H, W, 3) and neutrals (N, 3), got {images.shape} and {neutrals.shape}")
    return (images / neutrals[:, None, None, :]).astype(np.float32)


def srgb_to_white_balanced_camera(images, neutral, colour_model) -> np.ndarray:
    """Linear sRGB images (N, H, W, 3) -> the camera's white-balanced RGB at one white (`neutral`,
    (3,)); negative values (outside the camera's gamut) clipped to 0."""
    matrix = srgb_to_camera_matrices(np.asarray(neutral, np.float64).reshape(1, 3), colour_model)[0]
    return np.maximum(np.einsum("ij,nhwj->nhwi", matrix, np.asarray(images, np.float64)), 0.0).astype(np.float32)


def camera_rgb_to_linear_srgb(images, neutrals, colour_model) -> np.ndarray:
    """Real camera-RGB images (N, H, W, 3) and their as-shot neutrals (N, 3) -> white-balanced
    linear sRGB (N, H, W, 3) float32, negative values (out of the sRGB gamut) clipped to 0, each
    scaled to a maximum of 1. Zeroed (saturated) pixels stay 0."""
    balanced = white_balanced_camera_rgb(images, neutrals)
    to_srgb = np.linalg.inv(srgb_to_camera_matrices(neutrals, colour_model))
    linear = np.maximum(np.einsum("nij,nhwj->nhwi", to_srgb, balanced), 0.0)
    peak = np.maximum(linear.reshape(len(linear), -1).max(1), 1e-12)
    return (linear / peak[:, None, None, None]).astype(np.float32)
