"""The readout stage: a normalised signal mosaic -> the digital numbers the sensor writes.

In the order of `g2r_jax.pipeline.unprocess` (its steps 6-7): temporal noise at one ISO
(heteroscedastic Gaussian, Foi et al. 2008, the DNG NoiseProfile model, DNG spec 1.6 sec. 6:
`sensor.noise.model.add_noise`), row/column banding and early saturation
(`sensor.effects.apply_readout_effects`), then black/white levels, pedestal, defective pixels,
clipping and rounding (`sensor.effects.to_digital_numbers`). Every part is pure JAX: jit and
vmap `readout` over images and keys. The pipeline and the denoising training sets
(`g2r_jax.downstream.denoising.noise.synthetic_noisy`) both call it, so a synthetic noisy frame is the
simulation's own readout.
"""

from __future__ import annotations

from typing import NamedTuple, Optional

import jax.numpy as jnp
from jaxtyping import Array, Float

from g2r_jax.sensor.effects import SensorEffects, apply_readout_effects, no_effects, to_digital_numbers
from g2r_jax.sensor.noise.model import NoiseModel, add_noise, noise_level_at, noise_parameters


class ReadoutNoise(NamedTuple):
    """The noise of one ISO in normalised units (a pytree; a jit argument).

    Variance = `shot`[p] * x + `read`[p] at tile position p, or the level function
    `level_variance` (4, K) at `level_knots` (K,) when given; `correlation_kernel` (4, 3, 3)
    filters the draws within each CFA plane, its share by level `correlation_weight` (4, M) at
    `correlation_knots` (M,) (`g2r_jax.sensor.noise.shape`). None: absent."""

    shot: Float[Array, "4"]
    read: Float[Array, "4"]
    level_knots: Optional[Float[Array, "K"]] = None
    level_variance: Optional[Float[Array, "4 K"]] = None
    correlation_kernel: Optional[Float[Array, "4 3 3"]] = None
    correlation_knots: Optional[Float[Array, "M"]] = None
    correlation_weight: Optional[Float[Array, "4 M"]] = None


def noise_at_iso(noise: NoiseModel, iso) -> ReadoutNoise:
    """The `ReadoutNoise` of a profile's `NoiseModel` at `iso` (shot and read interpolated in ISO,
    `noise_parameters`; the level function's variances at `iso`, `noise_level_at`)."""
    shot, read = noise_parameters(iso, noise)
    return ReadoutNoise(shot=shot, read=read, level_knots=noise.level_knots, level_variance=noise_level_at(iso, noise),
                        correlation_kernel=noise.correlation_kernel, correlation_knots=noise.correlation_knots,
                        correlation_weight=noise.correlation_weight)


def readout(keys, signal, black_level, white_level, *, noise: ReadoutNoise | None = None,
            effects: SensorEffects | None = None, quantize: bool = True, valid_shape=None):
    """Read out a normalised signal mosaic: noise, banding and saturation, levels, quantisation.

    **Arguments:**
    - `keys`: two PRNG keys stacked, (2, ...) (e.g. `jax.random.split(key)`): the first draws the
      noise (a counter-based stream, one normal per pixel: `sensor.noise.stream`), the second the
      row/column banding.
    - `signal`: (H, W) mosaic, normalised (0 = black level, 1 = WhiteLevel), H and W even.
    - `black_level`: (4,) per tile position; `white_level`: scalar (DN).
    - `noise`: a `ReadoutNoise` (see `noise_at_iso`), or None for no temporal noise.
    - `effects`: the profile's `SensorEffects` (banding, clip level, pedestal, defective pixels),
      or None for an ideal readout (no banding, no pedestal, no defects).
    - `quantize`: round to uint16 DN (True) or keep float32 DN (False).
    - `valid_shape`: (h, w) of the image in the top-left of a zero-padded mosaic (the noise
      counters follow the image's own size; see `add_noise`).

    **Returns:** (H, W) DN mosaic in [0, WhiteLevel]: uint16 when `quantize`, else float32.
    """
    if noise is not None:
        signal = add_noise(keys[0], signal, noise.shot, noise.read, level_knots=noise.level_knots,
                           level_variance=noise.level_variance, correlation_kernel=noise.correlation_kernel,
                           valid_shape=valid_shape, correlation_levels=(noise.correlation_knots,
                                                                        noise.correlation_weight))
    if effects is not None:
        signal = apply_readout_effects(keys[1], signal, effects)
    return to_digital_numbers(signal, black_level, white_level, no_effects() if effects is None else effects,
                              quantize=quantize)


def banding_effects(row_noise_std, column_noise_std) -> SensorEffects:
    """`SensorEffects` with only row/column banding of these stds (normalised), every other effect
    absent: the readout of a sensor known only by its banding (clipping at WhiteLevel)."""
    ideal = no_effects()
    return SensorEffects(black_pedestal=ideal.black_pedestal, clip_level=ideal.clip_level,
                         channel_gain=ideal.channel_gain, shading=ideal.shading, defect_rows=ideal.defect_rows,
                         defect_cols=ideal.defect_cols, defect_values=ideal.defect_values,
                         row_noise_std=jnp.asarray(row_noise_std, jnp.float32),
                         column_noise_std=jnp.asarray(column_noise_std, jnp.float32))
