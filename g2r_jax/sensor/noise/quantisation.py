"""Rounding to integer DN counted once: the read term of a profile measured from integer raws.

The simulation ends by rounding to integer DN (`g2r_jax.sensor.effects.to_digital_numbers`),
which adds the rounding variance q = 1/12 DN^2 to every pixel (Widrow & Kollar, *Quantization
Noise*, 2008, ch. 4: for Gaussian noise of sigma >= 0.5 DN the variance of the rounded values is
sigma^2 + q within 3 %, wherever the level sits; below about 0.4 DN it depends on where the level
sits between two integers, and the subtraction is an estimate, low on an integer black level).
Read noise measured from integer raw data (a DNG NoiseProfile, a photon-transfer fit, the pixel
fallback) already holds q, so a profile keeps read - q, floored at 0, and says so with
`NoiseModel.read_excludes_quantisation`.
"""

from __future__ import annotations

import warnings

import jax.numpy as jnp
import numpy as np


def rounding_variance(black_level, white_level) -> np.ndarray:
    """(4,) rounding variance 1/12 DN^2 per tile position, in normalised units 1/12/(white - black)^2
    (also `estimation.quantisation_variance`; here without the estimators' scipy, for the converter)."""
    span = float(white_level) - np.resize(np.asarray(black_level, np.float64), 4)
    return 1.0 / 12.0 / span**2


def read_without_rounding(read, black_level, white_level) -> np.ndarray:
    """`read` (..., 4) measured from integer data, less the rounding variance, floored at 0."""
    return np.maximum(np.asarray(read, np.float64) - rounding_variance(black_level, white_level), 0.0)


def without_quantisation(noise, black_level, white_level):
    """`noise` (a `NoiseModel` whose read term was measured from integer raw data) with the rounding
    variance taken out of its read term and `read_excludes_quantisation` set; returned unchanged
    when the flag is already set. A noise level function (`level_variance`) is kept as it is: it is
    fitted without the rounding already (`g2r_jax.sensor.noise.extension`).

    **Arguments:** `noise`: the NoiseModel; `black_level` (4,) and `white_level`: the levels in DN
    the read term was measured at.

    **Returns:** a `NoiseModel`.
    """
    if noise.read_excludes_quantisation:
        return noise
    measured = np.asarray(noise.read, np.float64)
    rounding = rounding_variance(black_level, white_level)
    low = (measured > 0) & (measured < 2 * rounding)
    if np.any(low):
        sigma_dn = float(np.sqrt(np.min((measured / (12 * rounding))[low])))   # total measured sigma, in DN
        warnings.warn(f"read noise measured from integer data at {sigma_dn:.2f} DN, of which rounding to integer "
                      "DN is 0.29 DN: below about 0.4 DN the two cannot be told apart reliably; the read noise "
                      "before rounding may come out too low (docs: validation/dng_conformance)", stacklevel=2)
    read = read_without_rounding(measured, black_level, white_level)
    return type(noise)(iso=noise.iso, shot=noise.shot, read=jnp.asarray(read, noise.read.dtype),
                       iso_range=noise.iso_range, level_knots=noise.level_knots,
                       level_variance=noise.level_variance, correlation_kernel=noise.correlation_kernel,
                       correlation_knots=noise.correlation_knots, correlation_weight=noise.correlation_weight,
                       read_excludes_quantisation=True)


def rounded_gaussian_variance(sigma_dn, offset_dn) -> float:
    """Variance of round(offset + sigma n), n ~ N(0, 1), in DN^2: sum_k k^2 P_k - (sum_k k P_k)^2
    with P_k = Phi((k + 1/2 - offset) / sigma) - Phi((k - 1/2 - offset) / sigma) (Widrow & Kollar
    2008, ch. 4, without the sigma >= 0.5 DN approximation sigma^2 + 1/12)."""
    from scipy.special import ndtr

    sigma, offset = float(sigma_dn), float(offset_dn) % 1.0
    if sigma <= 0:
        return 0.0
    k = np.arange(np.floor(-10 * sigma - 2), np.ceil(10 * sigma + 3))
    p = ndtr((k + 0.5 - offset) / sigma) - ndtr((k - 0.5 - offset) / sigma)
    mean = np.sum(k * p)
    return float(np.sum(k * k * p) - mean * mean)


def variance_before_rounding(measured_dn2, offset_dn) -> float:
    """The Gaussian variance sigma^2 (DN^2) whose values around `offset_dn` (only its fraction of a
    DN matters) rounded to integers have variance `measured_dn2`: `rounded_gaussian_variance`
    inverted (bisection; it rises with sigma). Above 1 DN it is measured - 1/12 within 1e-6."""
    measured = float(measured_dn2)
    if measured <= 0:
        return 0.0
    low, high = 0.0, np.sqrt(measured) + 1.0
    for _ in range(60):
        middle = 0.5 * (low + high)
        if rounded_gaussian_variance(middle, offset_dn) < measured:
            low = middle
        else:
            high = middle
    return (0.5 * (low + high)) ** 2
