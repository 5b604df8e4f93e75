"""Sensor effects the simulation can add to a clean mosaic, each a small pure function.

Tile position p = 2 * (row % 2) + (col % 2) indexes every per-channel parameter; the effects
work on the (H, W) mosaic and pick each pixel's parameters by its position (`per_position`);
`to_planes`/`from_planes` convert to and from the four CFA planes (4, H/2, W/2). Values are
normalised signal x in [0, 1] (0 = black level, 1 = WhiteLevel) until `to_digital_numbers`.

Every effect of the audit vocabulary (`g2r_jax.audit`) has its parameters here, defaulting to
"no effect", so a profile extended by the audit produces exactly what it measured:
exposure (`ExposureModel`), noise (`NoiseModel`, heteroscedastic Gaussian: Foi et al. 2008,
as the DNG NoiseProfile tag, DNG spec 1.6 sec. 6), black pedestal, early clipping, green
imbalance, radial lens/colour shading, defective pixels and row/column banding (`SensorEffects`).
"""

from __future__ import annotations

from typing import Optional

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

    Optional shape of the noise (`g2r_jax.noise_shape`; None = absent, today's model):
    `level_knots` (K,) and `level_variance` (N, 4, K): a noise level function per ISO row and
    tile position, piecewise linear in x, used instead of shot * x + read; `correlation_kernel`
    (4, 3, 3): a spatial correlation kernel within each CFA plane.
    """

    iso: Float[Array, "N"]
    shot: Float[Array, "N 4"]
    read: Float[Array, "N 4"]
    iso_range: Float[Array, "2"]
    level_knots: Optional[Float[Array, "K"]] = None
    level_variance: Optional[Float[Array, "N 4 K"]] = None
    correlation_kernel: Optional[Float[Array, "4 3 3"]] = None


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


def noise_level_at(iso, noise: NoiseModel):
    """(4, K) noise level function variances at `iso`, or None when the model has none."""
    if noise.level_variance is None:
        return None
    from . import noise_shape

    return noise_shape.level_variance_at(iso, (noise.iso, noise.level_variance))


def add_noise(key, mosaic, shot, read, *, level_knots=None, level_variance=None, correlation_kernel=None):
    """Heteroscedastic Gaussian noise: x + sqrt(max(shot[p] * x + read[p], 0)) * N(0, 1).

    The draws are those of `jax.random.normal(key, (4, H/2, W/2))` on the planes layout, each
    read at its own pixel, so the noise does not depend on the layout the mosaic is held in.
    Optional shape (`g2r_jax.noise_shape`): `level_knots` (K,) with `level_variance` (4, K) at
    this ISO replace shot * x + read by that level function; `correlation_kernel` (4, 3, 3)
    filters the normals within each CFA plane (unit sum of squares: same variance)."""
    if level_variance is not None or correlation_kernel is not None:
        return _add_shaped_noise(key, mosaic, shot, read, level_knots, level_variance, correlation_kernel)
    variance = jnp.maximum(per_position(shot, mosaic.shape) * jnp.maximum(mosaic, 0)
                           + per_position(read, mosaic.shape), 0.0)
    return mosaic + jnp.sqrt(variance) * standard_normal_planes(key, mosaic.shape, mosaic.dtype)


def _add_shaped_noise(key, mosaic, shot, read, level_knots, level_variance, correlation_kernel):
    """`add_noise` with a noise level function and/or a correlation kernel, on the planes layout
    (same normals as `add_noise`: pixel (y, x) draws its plane element's normal)."""
    from . import noise_shape

    planes = to_planes(mosaic)
    if level_variance is not None:
        variance = noise_shape.level_function_planes(planes, level_knots, level_variance)
    else:
        variance = shot[:, None, None] * jnp.maximum(planes, 0) + read[:, None, None]
    normals = to_planes(standard_normal_planes(key, mosaic.shape, mosaic.dtype))
    if correlation_kernel is not None:
        normals = noise_shape.correlate_planes(normals, correlation_kernel.astype(mosaic.dtype))
    return from_planes(planes + jnp.sqrt(jnp.maximum(variance, 0.0)) * normals)


# ----------------------------------------------------------------------------- fast normal draws

_THREEFRY_ROTATIONS = ((13, 15, 26, 6), (17, 29, 16, 24))
_THREEFRY_PARITY = 0x1BD11BDA


def _threefry2x32(k0, k1, x0, x1):
    """Threefry-2x32 with 20 rounds (Salmon et al., "Parallel random numbers: as easy as
    1, 2, 3", SC 2011), written out round by round as JAX's own reference lowering is."""
    keys = (k0, k1, k0 ^ k1 ^ np.uint32(_THREEFRY_PARITY))
    x0, x1 = x0 + keys[0], x1 + keys[1]
    for block in range(5):
        for rotation in _THREEFRY_ROTATIONS[block % 2]:
            x0 = x0 + x1
            x1 = x0 ^ ((x1 << np.uint32(rotation)) | (x1 >> np.uint32(32 - rotation)))
        x0 = x0 + keys[(block + 1) % 3]
        x1 = x1 + keys[(block + 2) % 3] + np.uint32(block + 1)
    return x0, x1


def _fused_normal_applies(key, shape, dtype) -> bool:
    if jnp.dtype(dtype) != jnp.float32 or not jax.config.jax_threefry_partitionable:
        return False
    if int(np.prod(shape)) >= 2**32:
        return False
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        return str(jax.random.key_impl(key)) == "threefry2x32"
    return key.shape == (2,) and key.dtype == jnp.uint32 and jax.config.jax_default_prng_impl == "threefry2x32"


def standard_normal(key, shape, dtype=jnp.float32):
    """`jax.random.normal(key, shape, dtype)`, bit for bit, as one element-wise expression.

    JAX's CPU lowering of Threefry runs its 20 rounds as a 5-step loop over whole arrays, so a
    12-MP draw makes several passes through memory and cannot fuse with the noise that uses it.
    Here the same counter-based bits (JAX's partitionable scheme: the element's flat index as the
    counter, the two output words xor-ed), the same mantissa trick to a uniform in (-1, 1) and the
    same sqrt(2) erfinv(u) are written as plain element-wise operations, which XLA fuses with the
    consumer. Other key implementations, dtypes or settings fall back to `jax.random.normal`.
    """
    shape = tuple(shape)
    if not _fused_normal_applies(key, shape, dtype):
        return jax.random.normal(key, shape, dtype)
    return _normal_from_counter(key, jax.lax.iota(jnp.uint32, int(np.prod(shape))).reshape(shape))


def standard_normal_planes(key, mosaic_shape, dtype=jnp.float32):
    """`from_planes(jax.random.normal(key, (4, H/2, W/2), dtype))`, bit for bit, computed in
    place: pixel (y, x) takes the draw of its plane element, whose flat index (the Threefry
    counter) is p * (H/2 * W/2) + (y // 2) * (W/2) + x // 2 with p its tile position."""
    height, width = mosaic_shape
    planes_shape = (4, height // 2, width // 2)
    if not _fused_normal_applies(key, planes_shape, dtype):
        return from_planes(jax.random.normal(key, planes_shape, dtype))
    rows = jax.lax.broadcasted_iota(jnp.uint32, mosaic_shape, 0)
    cols = jax.lax.broadcasted_iota(jnp.uint32, mosaic_shape, 1)
    half_h, half_w = np.uint32(height // 2), np.uint32(width // 2)
    position = (rows & np.uint32(1)) * np.uint32(2) + (cols & np.uint32(1))
    counter = position * (half_h * half_w) + (rows >> np.uint32(1)) * half_w + (cols >> np.uint32(1))
    return _normal_from_counter(key, counter)


def _normal_from_counter(key, counter):
    """The normal draw of JAX's partitionable Threefry scheme at flat index `counter` (uint32)."""
    k0, k1 = jax.random.key_data(key) if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key) else key
    word0, word1 = _threefry2x32(k0, k1, jnp.zeros_like(counter), counter)
    bits = word0 ^ word1
    # 23 random mantissa bits under exponent 0: a float in [1, 2), then [0, 1), then (-1, 1).
    unit = jax.lax.bitcast_convert_type((bits >> np.uint32(9)) | np.uint32(0x3F800000), jnp.float32) - np.float32(1)
    low = np.nextafter(np.float32(-1), np.float32(0))
    uniform = jnp.maximum(low, unit * (np.float32(1) - low) + low)
    return np.float32(np.sqrt(2)) * jax.lax.erf_inv(uniform)


def per_position(values, mosaic_shape):
    """(4, ...) values per tile position -> (H, W, ...) value of every pixel's position.

    Written as selects on the row and column parity rather than a gather, so that XLA fuses and
    vectorises it with the element-wise arithmetic around it."""
    values = jnp.asarray(values)
    extra = values.ndim - 1
    rows = jax.lax.broadcasted_iota(jnp.int32, mosaic_shape, 0).reshape(mosaic_shape + (1,) * extra)
    cols = jax.lax.broadcasted_iota(jnp.int32, mosaic_shape, 1).reshape(mosaic_shape + (1,) * extra)
    odd_row, odd_col = (rows & 1) == 1, (cols & 1) == 1
    return jnp.where(odd_row, jnp.where(odd_col, values[3], values[2]), jnp.where(odd_col, values[1], values[0]))


def radial_distance_squared_mosaic(mosaic_shape, dtype=jnp.float32):
    """r^2 of every pixel (H, W); r = distance from the centre / half-diagonal (1 in the corners)."""
    height, width = mosaic_shape
    rows = jnp.arange(height, dtype=dtype) - (height - 1) / 2
    cols = jnp.arange(width, dtype=dtype) - (width - 1) / 2
    return (rows[:, None] ** 2 + cols[None, :] ** 2) / ((height - 1) ** 2 / 4 + (width - 1) ** 2 / 4)


def radial_distance_squared(plane_shape, dtype=jnp.float32):
    """r^2 of every full-mosaic pixel, as planes (4, H/2, W/2); r = 1 in the corners."""
    half_h, half_w = plane_shape
    return to_planes(radial_distance_squared_mosaic((2 * half_h, 2 * half_w), dtype))


def shading_gain_mosaic(mosaic_shape, shading, dtype=jnp.float32):
    """Radial gain 1 + a1[p] r^2 + a2[p] r^4 of every pixel (H, W)."""
    r2 = radial_distance_squared_mosaic(mosaic_shape, dtype)
    coefficients = per_position(shading, mosaic_shape)
    return 1.0 + coefficients[..., 0] * r2 + coefficients[..., 1] * r2**2


def to_planes(mosaic):
    """(H, W) mosaic -> (4, H/2, W/2) planes in tile order (0,0), (0,1), (1,0), (1,1)."""
    height, width = mosaic.shape
    return mosaic.reshape(height // 2, 2, width // 2, 2).transpose(1, 3, 0, 2).reshape(4, height // 2, width // 2)


def from_planes(planes):
    """(4, H/2, W/2) planes -> (H, W) mosaic (inverse of `to_planes`)."""
    _, half_h, half_w = planes.shape
    tile = planes.reshape(2, 2, half_h, half_w)
    return tile.transpose(2, 0, 3, 1).reshape(2 * half_h, 2 * half_w)


# The effects below work on the normalised mosaic (H, W) itself, per-position parameters being
# selected pixel by pixel (`per_position`): in this layout XLA fuses the whole chain from the
# 8-bit input to the uint16 output into one vectorised loop.

def apply_optical_effects(mosaic, effects: SensorEffects):
    """Effects on the light reaching each pixel: lens/colour shading and per-channel gain."""
    gain = shading_gain_mosaic(mosaic.shape, effects.shading, mosaic.dtype)
    return mosaic * gain * per_position(effects.channel_gain, mosaic.shape)


def apply_readout_effects(key, mosaic, effects: SensorEffects):
    """Effects of the readout on the normalised signal: banding, then early saturation."""
    k_rows, k_cols = jax.random.split(key)
    height, width = mosaic.shape
    row_offsets = effects.row_noise_std * jax.random.normal(k_rows, (height,), mosaic.dtype)
    col_offsets = effects.column_noise_std * jax.random.normal(k_cols, (width,), mosaic.dtype)
    mosaic = mosaic + (row_offsets[:, None] + col_offsets[None, :])
    return jnp.minimum(mosaic, effects.clip_level)


def to_digital_numbers(mosaic, black_level, white_level, effects: SensorEffects, *, quantize=True):
    """Normalised mosaic -> DN mosaic (H, W): scale to [black, white], add the pedestal, set
    defective pixels, round and clip to [0, WhiteLevel]."""
    black = per_position(black_level, mosaic.shape)
    digital = black + mosaic * (white_level - black) + per_position(effects.black_pedestal, mosaic.shape)
    if effects.defect_rows.shape[0]:
        black_at = black_level[2 * (effects.defect_rows % 2) + effects.defect_cols % 2]
        defect_dn = black_at + effects.defect_values * (white_level - black_at)
        digital = digital.at[effects.defect_rows, effects.defect_cols].set(defect_dn, mode="drop")
    digital = jnp.clip(digital, 0.0, white_level)
    return jnp.round(digital).astype(jnp.uint16) if quantize else digital
