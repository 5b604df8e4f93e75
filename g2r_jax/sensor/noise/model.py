"""The noise model: heteroscedastic Gaussian noise per ISO and tile position (Foi et al. 2008, as
the DNG NoiseProfile tag, DNG spec 1.6 sec. 6), optionally with a shaped level function and a
spatial correlation (`g2r_jax.sensor.noise.shape`)."""

from __future__ import annotations

from typing import Optional

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from g2r_jax.sensor.layout import from_planes, per_position, to_planes
from g2r_jax.sensor.noise.stream import _normal_from_counter, standard_normal_planes


class NoiseModel(eqx.Module):
    """Noise variance = shot(ISO)[p] * x + read(ISO)[p] for tile position p, x normalised.

    `iso` is ascending; shot/read are interpolated linearly in ISO between rows and held
    constant outside. `iso_range` bounds the log-uniform ISO draw when none is given.

    Optional shape of the noise (`g2r_jax.sensor.noise.shape`; None = absent, today's model):
    `level_knots` (K,) and `level_variance` (N, 4, K): a noise level function per ISO row and
    tile position, piecewise linear in x, used instead of shot * x + read; `correlation_kernel`
    (4, 3, 3): a spatial correlation kernel within each CFA plane; `correlation_knots` (M,) and
    `correlation_weight` (4, M): the kernel's share by signal level (absent: the kernel everywhere).

    `read_excludes_quantisation`: the read term is the noise before rounding to integer DN (the
    simulation adds the rounding, 1/12 DN^2, itself); set where a read term measured from integer
    raw data had the rounding taken out (`g2r_jax.sensor.noise.quantisation`). False: the read term
    is used as given (profiles that do not say).
    """

    iso: Float[Array, "N"]
    shot: Float[Array, "N 4"]
    read: Float[Array, "N 4"]
    iso_range: Float[Array, "2"]
    level_knots: Optional[Float[Array, "K"]] = None
    level_variance: Optional[Float[Array, "N 4 K"]] = None
    correlation_kernel: Optional[Float[Array, "4 3 3"]] = None
    correlation_knots: Optional[Float[Array, "M"]] = None
    correlation_weight: Optional[Float[Array, "4 M"]] = None
    read_excludes_quantisation: bool = eqx.field(static=True, default=False)


def sample_iso(key, noise: NoiseModel):
    """ISO drawn log-uniformly in `iso_range`."""
    low, high = jnp.log(noise.iso_range[0]), jnp.log(noise.iso_range[1])
    return jnp.exp(jax.random.uniform(key, (), noise.iso.dtype, low, high))


def noise_parameters(iso, noise: NoiseModel):
    """(shot (4,), read (4,)) at `iso`, linear interpolation in ISO between calibrated rows."""
    interpolate = jax.vmap(lambda column: jnp.interp(iso, noise.iso, column), in_axes=1)
    return interpolate(noise.shot), interpolate(noise.read)


def noise_level_at(iso, noise: NoiseModel):
    """(4, K) noise level function variances at `iso`, or None when the model has none."""
    if noise.level_variance is None:
        return None
    from g2r_jax.sensor.noise import shape as noise_shape

    return noise_shape.level_variance_at(iso, (noise.iso, noise.level_variance))


def add_noise(key, mosaic, shot, read, *, level_knots=None, level_variance=None, correlation_kernel=None,
              valid_shape=None, correlation_levels=None):
    """Heteroscedastic Gaussian noise: x + sqrt(max(shot[p] * x + read[p], 0)) * N(0, 1).

    The draws are `standard_normal(key, (H, W))`, one per pixel (`standard_normal_planes`),
    so the noise does not depend on the layout the mosaic is held in; `valid_shape`: (h, w) of
    the image in the top-left of a zero-padded mosaic (the image's own draws).
    Optional shape (`g2r_jax.sensor.noise.shape`): `level_knots` (K,) with `level_variance` (4, K) at
    this ISO replace shot * x + read by that level function; `correlation_kernel` (4, 3, 3)
    filters the normals within each CFA plane (unit sum of squares: same variance);
    `correlation_levels` (knots (M,), weight (4, M)) or None: the kernel's share by signal level."""
    if level_variance is not None or correlation_kernel is not None:
        return _add_shaped_noise(key, mosaic, shot, read, level_knots, level_variance, correlation_kernel,
                                 valid_shape, correlation_levels)
    variance = jnp.maximum(per_position(shot, mosaic.shape) * jnp.maximum(mosaic, 0)
                           + per_position(read, mosaic.shape), 0.0)
    return mosaic + jnp.sqrt(variance) * standard_normal_planes(key, mosaic.shape, mosaic.dtype, valid_shape=valid_shape)


def _add_shaped_noise(key, mosaic, shot, read, level_knots, level_variance, correlation_kernel, valid_shape=None,
                      correlation_levels=None):
    """`add_noise` with a noise level function and/or a correlation kernel (`noise_shape`): the
    same stream of draws, each pixel's own, filtered within its CFA plane when a kernel is given."""
    from g2r_jax.sensor.noise import shape as noise_shape

    if level_variance is not None:
        variance = from_planes(noise_shape.level_function_planes(to_planes(mosaic), level_knots, level_variance))
    else:
        variance = per_position(shot, mosaic.shape) * jnp.maximum(mosaic, 0) + per_position(read, mosaic.shape)
    if correlation_kernel is None:
        normals = standard_normal_planes(key, mosaic.shape, mosaic.dtype, valid_shape=valid_shape)
    else:
        normal_at = lambda counter: _normal_from_counter(key, counter).astype(mosaic.dtype)
        knots, weight = correlation_levels if correlation_levels is not None else (None, None)
        if weight is not None:
            weight = from_planes(noise_shape.level_function_planes(to_planes(mosaic), knots.astype(mosaic.dtype),
                                                                   weight.astype(mosaic.dtype)))
        normals = noise_shape.correlated_normals(normal_at, mosaic.shape, correlation_kernel.astype(mosaic.dtype),
                                                 per_position, valid_shape, weight)
    return mosaic + jnp.sqrt(jnp.maximum(variance, 0.0)) * normals
