"""Sensor effects the simulation can add to a clean mosaic, each a small pure function.

The mosaic is handled as its four CFA planes, shape (4, H/2, W/2), plane p holding tile
position p = 2 * (row % 2) + (col % 2). Values are normalised signal x in [0, 1] (0 = black
level, 1 = WhiteLevel) until `to_digital_numbers`.

Every effect of the audit vocabulary (`g2r_jax.audit`) has its parameters here, defaulting to
"no effect", so a profile extended by the audit produces exactly what it measured:
exposure (`ExposureModel`), noise (`NoiseModel`, heteroscedastic Gaussian: Foi et al. 2008,
as the DNG NoiseProfile tag, DNG spec 1.6 sec. 6), black pedestal, early clipping, green
imbalance, radial lens/colour shading, defective pixels and row/column banding (`SensorEffects`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int


class ExposureModel(eqx.Module):
    """Global exposure gain 2**e with e ~ Normal(log2_mean, log2_std) per image."""

    log2_mean: Float[Array, ""]
    log2_std: Float[Array, ""]


class NoiseModel(eqx.Module):
    """Noise variance = shot(ISO)[p] * x + read(ISO)[p] for tile position p, x normalised.

    `iso` is ascending; shot/read are interpolated linearly in ISO between rows and held
    constant outside. `iso_range` bounds the log-uniform ISO draw when none is given.
    """

    iso: Float[Array, "N"]
    shot: Float[Array, "N 4"]
    read: Float[Array, "N 4"]
    iso_range: Float[Array, "2"]


class SensorEffects(eqx.Module):
    """Parameters of the non-ideal sensor effects; defaults mean 'absent'.

    - `black_pedestal` (4,): DN added to every pixel of tile position p on top of BlackLevel.
    - `clip_level`: normalised level where the sensor saturates (1 = at WhiteLevel).
    - `channel_gain` (4,): multiplicative gain per tile position (green imbalance = the two
      green positions differing).
    - `shading` (4, 2): per tile position, gain = 1 + a1 r^2 + a2 r^4, r = distance from the
      centre divided by the half-diagonal (1 in the corners).
    - `defect_rows`, `defect_cols`, `defect_values`: fixed defective pixels (full-mosaic
      coordinates) and the normalised value they read (1 = hot/stuck high, 0 = dead).
    - `row_noise_std`, `column_noise_std`: std (normalised) of a per-file offset drawn for
      every row / column of the mosaic (banding).
    """

    black_pedestal: Float[Array, "4"]
    clip_level: Float[Array, ""]
    channel_gain: Float[Array, "4"]
    shading: Float[Array, "4 2"]
    defect_rows: Int[Array, "D"]
    defect_cols: Int[Array, "D"]
    defect_values: Float[Array, "D"]
    row_noise_std: Float[Array, ""]
    column_noise_std: Float[Array, ""]


def no_effects(dtype=np.float32) -> SensorEffects:
    """SensorEffects that change nothing."""
    return SensorEffects(
        black_pedestal=jnp.zeros(4, dtype), clip_level=jnp.asarray(1.0, dtype),
        channel_gain=jnp.ones(4, dtype), shading=jnp.zeros((4, 2), dtype),
        defect_rows=jnp.zeros(0, jnp.int32), defect_cols=jnp.zeros(0, jnp.int32),
        defect_values=jnp.zeros(0, dtype), row_noise_std=jnp.asarray(0.0, dtype),
        column_noise_std=jnp.asarray(0.0, dtype))


def fixed_exposure(dtype=np.float32) -> ExposureModel:
    """No random exposure: gain 1."""
    return ExposureModel(log2_mean=jnp.asarray(0.0, dtype), log2_std=jnp.asarray(0.0, dtype))


def sample_exposure_gain(key, exposure: ExposureModel):
    """Global gain 2**e, e ~ Normal(log2_mean, log2_std)."""
    return 2.0 ** (exposure.log2_mean + exposure.log2_std * jax.random.normal(key, (), exposure.log2_mean.dtype))


def sample_iso(key, noise: NoiseModel):
    """ISO drawn log-uniformly in `iso_range`."""
    low, high = jnp.log(noise.iso_range[0]), jnp.log(noise.iso_range[1])
    return jnp.exp(jax.random.uniform(key, (), noise.iso.dtype, low, high))


def noise_parameters(iso, noise: NoiseModel):
    """(shot (4,), read (4,)) at `iso`, linear interpolation in ISO between calibrated rows."""
    interpolate = jax.vmap(lambda column: jnp.interp(iso, noise.iso, column), in_axes=1)
    return interpolate(noise.shot), interpolate(noise.read)


def add_noise(key, planes, shot, read):
    """Heteroscedastic Gaussian noise: x + sqrt(max(shot * x + read, 0)) * N(0, 1) per plane."""
    variance = jnp.maximum(shot[:, None, None] * jnp.maximum(planes, 0) + read[:, None, None], 0.0)
    return planes + jnp.sqrt(variance) * jax.random.normal(key, planes.shape, planes.dtype)


def radial_distance_squared(plane_shape, dtype=jnp.float32):
    """r^2 of every full-mosaic pixel, as planes (4, H/2, W/2); r = 1 in the corners."""
    half_h, half_w = plane_shape
    height, width = 2 * half_h, 2 * half_w
    rows = jnp.arange(height, dtype=dtype) - (height - 1) / 2
    cols = jnp.arange(width, dtype=dtype) - (width - 1) / 2
    r2 = (rows[:, None] ** 2 + cols[None, :] ** 2) / ((height - 1) ** 2 / 4 + (width - 1) ** 2 / 4)
    return to_planes(r2)


def shading_gain(plane_shape, shading, dtype=jnp.float32):
    """Per-plane radial gain 1 + a1 r^2 + a2 r^4 (4, H/2, W/2)."""
    r2 = radial_distance_squared(plane_shape, dtype)
    return 1.0 + shading[:, 0, None, None] * r2 + shading[:, 1, None, None] * r2**2


def to_planes(mosaic):
    """(H, W) mosaic -> (4, H/2, W/2) planes in tile order (0,0), (0,1), (1,0), (1,1)."""
    return jnp.stack([mosaic[0::2, 0::2], mosaic[0::2, 1::2], mosaic[1::2, 0::2], mosaic[1::2, 1::2]])


def from_planes(planes):
    """(4, H/2, W/2) planes -> (H, W) mosaic (inverse of `to_planes`)."""
    _, half_h, half_w = planes.shape
    tile = planes.reshape(2, 2, half_h, half_w)
    return tile.transpose(2, 0, 3, 1).reshape(2 * half_h, 2 * half_w)


def apply_optical_effects(planes, effects: SensorEffects):
    """Effects on the light reaching each pixel: lens/colour shading and per-channel gain."""
    gain = shading_gain(planes.shape[1:], effects.shading, planes.dtype)
    return planes * gain * effects.channel_gain[:, None, None]


def apply_readout_effects(key, planes, effects: SensorEffects):
    """Effects of the readout on the normalised signal: banding, then early saturation."""
    k_rows, k_cols = jax.random.split(key)
    _, half_h, half_w = planes.shape
    row_offsets = effects.row_noise_std * jax.random.normal(k_rows, (2 * half_h,), planes.dtype)
    col_offsets = effects.column_noise_std * jax.random.normal(k_cols, (2 * half_w,), planes.dtype)
    banding = row_offsets[:, None] + col_offsets[None, :]
    planes = planes + to_planes(banding)
    return jnp.minimum(planes, effects.clip_level)


def to_digital_numbers(planes, black_level, white_level, effects: SensorEffects, *, quantize=True):
    """Normalised planes -> DN mosaic (H, W): scale to [black, white], add the pedestal, set
    defective pixels, round and clip to [0, WhiteLevel]."""
    black = black_level[:, None, None]
    digital = black + planes * (white_level - black) + effects.black_pedestal[:, None, None]
    mosaic = from_planes(digital)
    if effects.defect_rows.shape[0]:
        black_full = from_planes(jnp.broadcast_to(black, planes.shape))
        defect_dn = black_full[effects.defect_rows, effects.defect_cols] + effects.defect_values * (
            white_level - black_full[effects.defect_rows, effects.defect_cols])
        mosaic = mosaic.at[effects.defect_rows, effects.defect_cols].set(defect_dn, mode="drop")
    mosaic = jnp.clip(mosaic, 0.0, white_level)
    return jnp.round(mosaic).astype(jnp.uint16) if quantize else mosaic
