"""Where a neural ISP's colour error lies: how much of its CIEDE2000 to the target is one global
colour correction of the image away (its white balance, or its colour matrix), and how much is
left in the tone and the local detail.

Each predicted image is corrected by the correction that brings it closest to its own target in
linear sRGB (weighted least squares over the measured pixels): per-channel gains (a von Kries
white balance, von Kries 1902; the form of the DNG's AsShotNeutral) or a full 3 x 3 matrix (a
white balance and a colour matrix together). The error left after the gains is what a perfect
white balance of that image would not fix; what the gains remove is the white-balance share (gains
also take out a global error of brightness, the exposure, and the mean level of a tone error). The
correction sees the target, so these are diagnoses of a trained network, not measures of a
deployable one.
"""

from __future__ import annotations

import numpy as np

PARTS = {"delta_e_balance": "ΔE2000 left after each image's best white balance (per-channel gains)",
         "delta_e_colour": "ΔE2000 left after each image's best 3 x 3 colour correction"}


def _linear(srgb: np.ndarray) -> np.ndarray:
    from g2r_jax.downstream.isp.net import srgb_decoded

    return srgb_decoded(srgb)


def _encoded(linear: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 encoding, clipped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def _weights(mask, shape) -> np.ndarray:
    return np.ones(shape[:3]) if mask is None else np.asarray(mask, np.float64).reshape(shape[:3])


def best_gains(predicted: np.ndarray, target: np.ndarray, mask=None) -> np.ndarray:
    """(N, 3) gains g minimising sum_w (g_c p_c - t_c)^2 per image and channel in linear light.

    **Arguments:** `predicted`, `target` (N, H, W, 3) sRGB-coded in [0, 1]; `mask` (N, H, W) the
    pixels that count (default all). **Returns:** the gains (1 where a channel holds nothing)."""
    p, t = _linear(predicted), _linear(target)
    w = _weights(mask, p.shape)[..., None]
    num, den = (w * p * t).sum(axis=(1, 2)), (w * p * p).sum(axis=(1, 2))
    return np.where(den > 1e-12, num / np.maximum(den, 1e-12), 1.0)


def best_matrices(predicted: np.ndarray, target: np.ndarray, mask=None) -> np.ndarray:
    """(N, 3, 3) matrices M minimising sum_w |M p - t|^2 per image in linear light (a small ridge
    toward the best gains keeps an image of too few colours well posed).

    **Arguments:** as `best_gains`. **Returns:** the matrices (applied as `M @ p`)."""
    p, t = _linear(predicted), _linear(target)
    w = _weights(mask, p.shape)
    out = np.empty((len(p), 3, 3))
    for i, gains in enumerate(best_gains(predicted, target, mask)):
        pw = p[i].reshape(-1, 3) * w[i].reshape(-1, 1)
        gram = pw.T @ p[i].reshape(-1, 3)
        ridge = 1e-6 * max(np.trace(gram), 1e-12)
        out[i] = np.linalg.solve(gram + ridge * np.eye(3), pw.T @ t[i].reshape(-1, 3) + ridge * np.diag(gains)).T
    return out


def corrected(predicted: np.ndarray, target: np.ndarray, mask=None, *, kind: str = "gains") -> np.ndarray:
    """`predicted` (sRGB-coded) after its best correction toward `target` (`kind` 'gains' or
    'matrix'), sRGB-coded and clipped to [0, 1]. **Returns:** (N, H, W, 3)."""
    p = _linear(predicted)
    if kind == "gains":
        return _encoded(p * best_gains(predicted, target, mask)[:, None, None, :])
    if kind == "matrix":
        return _encoded(np.einsum("nij,nhwj->nhwi", best_matrices(predicted, target, mask), p))
    raise ValueError(f"unknown correction {kind!r}; expected 'gains' or 'matrix'")


def error_parts(predicted: np.ndarray, target: np.ndarray, mask=None) -> dict:
    """{'delta_e_balance', 'delta_e_colour'}: each (N,) the per-image mean CIEDE2000
    (`net.delta_e_2000`) left after the best gains and after the best 3 x 3 matrix (`PARTS`).

    **Arguments:** `predicted`, `target` (N, H, W, 3) sRGB-coded in [0, 1]; `mask` (N, H, W).
    **Returns:** the dict."""
    from g2r_jax.downstream.isp.net import delta_e_2000

    return {"delta_e_balance": delta_e_2000(corrected(predicted, target, mask, kind="gains"), target, mask),
            "delta_e_colour": delta_e_2000(corrected(predicted, target, mask, kind="matrix"), target, mask)}
