"""Exposure: the global gain of each image, 2**e with e drawn per image."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float


class ExposureModel(eqx.Module):
    """Global exposure gain 2**e with e ~ Normal(log2_mean, log2_std) per image."""

    log2_mean: Float[Array, ""]
    log2_std: Float[Array, ""]


def fixed_exposure(dtype=np.float32) -> ExposureModel:
    """No random exposure: gain 1."""
    return ExposureModel(log2_mean=jnp.asarray(0.0, dtype), log2_std=jnp.asarray(0.0, dtype))


def sample_exposure_gain(key, exposure: ExposureModel):
    """Global gain 2**e, e ~ Normal(log2_mean, log2_std)."""
    return 2.0 ** (exposure.log2_mean + exposure.log2_std * jax.random.normal(key, (), exposure.log2_mean.dtype))
