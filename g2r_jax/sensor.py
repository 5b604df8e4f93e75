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


def add_noise(key, mosaic, shot, read, *, level_knots=None, level_variance=None, correlation_kernel=None,
              valid_shape=None):
    """Heteroscedastic Gaussian noise: x + sqrt(max(shot[p] * x + read[p], 0)) * N(0, 1).

    The draws are `standard_normal(key, (H, W))`, one per pixel (`standard_normal_planes`),
    so the noise does not depend on the layout the mosaic is held in; `valid_shape`: (h, w) of
    the image in the top-left of a zero-padded mosaic (the image's own draws).
    Optional shape (`g2r_jax.noise_shape`): `level_knots` (K,) with `level_variance` (4, K) at
    this ISO replace shot * x + read by that level function; `correlation_kernel` (4, 3, 3)
    filters the normals within each CFA plane (unit sum of squares: same variance)."""
    if level_variance is not None or correlation_kernel is not None:
        return _add_shaped_noise(key, mosaic, shot, read, level_knots, level_variance, correlation_kernel,
                                 valid_shape)
    variance = jnp.maximum(per_position(shot, mosaic.shape) * jnp.maximum(mosaic, 0)
                           + per_position(read, mosaic.shape), 0.0)
    return mosaic + jnp.sqrt(variance) * standard_normal_planes(key, mosaic.shape, mosaic.dtype, valid_shape=valid_shape)


def _add_shaped_noise(key, mosaic, shot, read, level_knots, level_variance, correlation_kernel, valid_shape=None):
    """`add_noise` with a noise level function and/or a correlation kernel (`noise_shape`): the
    same stream of draws, each pixel's own, filtered within its CFA plane when a kernel is given."""
    from . import noise_shape

    if level_variance is not None:
        variance = from_planes(noise_shape.level_function_planes(to_planes(mosaic), level_knots, level_variance))
    else:
        variance = per_position(shot, mosaic.shape) * jnp.maximum(mosaic, 0) + per_position(read, mosaic.shape)
    if correlation_kernel is None:
        normals = standard_normal_planes(key, mosaic.shape, mosaic.dtype, valid_shape=valid_shape)
    else:
        normal_at = lambda counter: _normal_from_counter(key, counter).astype(mosaic.dtype)
        normals = noise_shape.correlated_normals(normal_at, mosaic.shape, correlation_kernel.astype(mosaic.dtype),
                                                 per_position, valid_shape)
    return mosaic + jnp.sqrt(jnp.maximum(variance, 0.0)) * normals


# ----------------------------------------------------------------------------- fast normal draws
#
# The noise stream. Each pixel's normal is a pure function of (key, counter), the counter being
# the element's flat index, so draws do not depend on batching, sharding or padding:
#   bits   = mix32(mix32(counter ^ k0) + k1)          (k0, k1: the key's two 32-bit words)
#   v      = ((bits >> 8 & 0x7FFFFF) + 1/2) / 2**24   (23 bits: a probability in (0, 1/2))
#   normal = -Q(v) if the top bit is set else Q(v)    (Q: the standard normal quantile, < 0)
# mix32 is Wellons' "lowbias32" integer hash (two xorshift-multiply rounds; hash-prospector,
# github.com/skeeto/hash-prospector). Q is a polynomial in t = sqrt(-ln v), on which the normal
# quantile is smooth over the whole range (the variable of the tail approximations of Wichura,
# "Algorithm AS 241", Applied Statistics 37, 1988): degree 11 in t rescaled to [-1, 1], a least-
# squares Chebyshev fit to scipy's `ndtri` at 400,001 points geometric in v over [2**-25, 1/2]
# (`_quantile_coefficients` refits it; error < 7e-6 at every one of the 2**23 values of v, tails
# to |z| = 5.42). ln v comes from the float's exponent and a degree-7 polynomial of its mantissa
# (the same kind of fit to log1p on [0, 1], error < 6e-7), so the draw is a few dozen vectorised
# float operations, no look-up and no library call: XLA fuses it into the pixel loop. History:
# `jax.random.normal` (Threefry + erfinv, 4.5x the rest of the pipeline on CPU), then a
# 1537-entry quantile table (its gather kept noise at 1.66x noise off on 2 CPU cores), now this;
# each change altered the noisy outputs of a given seed.

_MIX_MULTIPLIERS = (0x21F0AAAD, 0x735A2D97)      # lowbias32 (Wellons, hash-prospector)
_T_RANGE = (0.8325546111576977, 4.162773055788489)   # sqrt(ln 2), sqrt(25 ln 2): t over v in [2**-25, 1/2]
# Q(v) = sum_i QUANTILE[i] * s**i, s = (2 t - t0 - t1) / (t1 - t0); float32 values of the fit
_QUANTILE = (-2.8856353759765625, -2.6181082725524902, 0.12596362829208374, -0.06433083862066269,
             0.03363639488816261, -0.018324974924325943, 0.012453104369342327, -0.007107526995241642,
             -0.000465595192508772, 0.000331281014950946, 0.004052435979247093, -0.002448810962960124)
# ln(1 + f) = sum_i LOG1P[i] * x**i, x = 2 f - 1, f in [0, 1)
_LOG1P = (0.4054652452468872, 0.33333316445350647, -0.05556004121899605, 0.012348315678536892,
          -0.003062246832996607, 0.0008129912312142551, -0.0002688723034225404, 7.905407983344048e-05)


def _mix32(x):
    """lowbias32: a bijective 32-bit integer hash with near-ideal avalanche (Wellons)."""
    x = x ^ (x >> np.uint32(16))
    x = x * np.uint32(_MIX_MULTIPLIERS[0])
    x = x ^ (x >> np.uint32(15))
    x = x * np.uint32(_MIX_MULTIPLIERS[1])
    return x ^ (x >> np.uint32(15))


def _key_words(key):
    """The key as two uint32 words (k0, k1): Threefry keys are two words; longer key data (other
    `jax.random` implementations) is folded by xor into two."""
    data = jax.random.key_data(key) if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key) else key
    data = jnp.asarray(data).astype(jnp.uint32)
    if data.shape[-1] == 2:
        return data[..., 0], data[..., 1]
    words = data.reshape(data.shape[:-1] + (-1, 2))
    folded = jax.lax.reduce(words, np.uint32(0), jax.lax.bitwise_xor, (words.ndim - 2,))
    return folded[..., 0], folded[..., 1]


def _counter_bits(key, counter):
    """32 random bits for each uint32 `counter` under `key`."""
    k0, k1 = _key_words(key)
    return _mix32(_mix32(counter ^ k0) + k1)


def _quantile_coefficients(degree: int = 11, log_degree: int = 7):
    """Refit the two polynomials above (float64): the fits that `_QUANTILE` and `_LOG1P` hold."""
    from numpy.polynomial import chebyshev
    from scipy.special import ndtri

    v = np.geomspace(2.0**-25, 0.5, 400_001)
    t0, t1 = _T_RANGE
    s = (2 * np.sqrt(-np.log(v)) - t0 - t1) / (t1 - t0)
    quantile = chebyshev.cheb2poly(chebyshev.chebfit(s, ndtri(v), degree))
    f = np.linspace(0.0, 1.0, 100_001)
    log1p = chebyshev.cheb2poly(chebyshev.chebfit(2 * f - 1, np.log1p(f), log_degree))
    return quantile, log1p


def _polynomial(coefficients, x):
    """sum_i coefficients[i] * x**i by Estrin's scheme (pairs, then pairs of pairs): a dependency
    chain of log2(degree) multiply-adds instead of Horner's degree, so the long fused pixel loop
    is not bound by its latency (Knuth, TAOCP vol. 2, 4.6.4)."""
    terms = [np.float32(c) + np.float32(d) * x for c, d in zip(coefficients[0::2], coefficients[1::2])]
    if len(coefficients) % 2:
        terms.append(jnp.full_like(x, coefficients[-1]))
    power = x
    while len(terms) > 1:
        power = power * power
        terms = [terms[i] + power * terms[i + 1] if i + 1 < len(terms) else terms[i] for i in range(0, len(terms), 2)]
    return terms[0]


def _quantile_of_mantissa(mantissa):
    """Q(v), v = (mantissa + 1/2) / 2**24, for int32 `mantissa` in [0, 2**23): float32, < 0."""
    w = mantissa.astype(jnp.float32) + np.float32(0.5)                  # exact: 24 bits
    w_bits = jax.lax.bitcast_convert_type(w, jnp.int32)
    exponent = ((w_bits >> 23) - 127).astype(jnp.float32)
    fraction = jax.lax.bitcast_convert_type((w_bits & 0x7FFFFF) | 0x3F800000, jnp.float32)   # in [1, 2)
    ln_w = exponent * np.float32(np.log(2.0)) + _polynomial(_LOG1P, np.float32(2.0) * fraction - np.float32(3.0))
    t = jnp.sqrt(np.float32(24 * np.log(2.0)) - ln_w)                   # sqrt(-ln v)
    t0, t1 = _T_RANGE
    s = (np.float32(2.0) * t - np.float32(t0 + t1)) * np.float32(1.0 / (t1 - t0))
    return _polynomial(_QUANTILE, s)


def _normal_from_bits(bits):
    """Standard normal float32 from 32 random bits (see the stream above)."""
    mantissa = ((bits >> np.uint32(8)) & np.uint32(0x7FFFFF)).astype(jnp.int32)
    quantile = _quantile_of_mantissa(mantissa)
    return jnp.where((bits >> np.uint32(31)) == np.uint32(1), -quantile, quantile)


def _normal_from_counter(key, counter):
    """The stream's standard normal (float32) at uint32 `counter` under `key`."""
    return _normal_from_bits(_counter_bits(key, counter))


def _check_count(count: int) -> None:
    if count >= 2**32:
        raise ValueError(f"{count} draws exceed the 2**32 counters of one key; split the key")


def standard_normal(key, shape, dtype=jnp.float32):
    """Standard normal draws of `shape`: element i (flat, C order) is the stream's draw at
    counter i under `key` (see the stream above), computed in float32 and cast to `dtype`.

    Element-wise, so under jit it fuses with its consumer; vmap over keys gives each key its own
    draws, identical to drawing key by key."""
    shape = tuple(shape)
    count = int(np.prod(shape))
    _check_count(count)
    counter = jax.lax.iota(jnp.uint32, count).reshape(shape)
    return _normal_from_counter(key, counter).astype(dtype)


def standard_normal_planes(key, mosaic_shape, dtype=jnp.float32, *, valid_shape=None):
    """The noise draws of an (H, W) mosaic: pixel (y, x) takes the stream's draw at counter
    y * W + x, i.e. `standard_normal(key, (H, W), dtype)`; the name stays from the time the
    draws were made in the CFA planes layout.

    With `valid_shape` (h, w) (ints or traced), the counter is y * w + x: the top-left h x w of a
    larger mosaic gets exactly the draws of an h x w mosaic (for zero-padded batches)."""
    _check_count(int(np.prod(mosaic_shape)))
    width = mosaic_shape[1] if valid_shape is None else valid_shape[1]
    rows = jax.lax.broadcasted_iota(jnp.uint32, mosaic_shape, 0)
    cols = jax.lax.broadcasted_iota(jnp.uint32, mosaic_shape, 1)
    counter = rows * jnp.asarray(width).astype(jnp.uint32) + cols
    return _normal_from_counter(key, counter).astype(dtype)


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


def radial_distance_squared_mosaic(mosaic_shape, dtype=jnp.float32, *, valid_shape=None):
    """r^2 of every pixel (H, W); r = distance from the centre / half-diagonal (1 in the corners).

    With `valid_shape` (h, w) (ints or traced int32), the image is the top-left h x w of a
    zero-padded mosaic and r is measured for that image. Computed as the integer ratio
    ((2y - h + 1)^2 + (2x - w + 1)^2) / ((h - 1)^2 + (w - 1)^2), converted to float only for the
    final division: the same bits whether the sizes are constants or traced (sizes < 32768)."""
    height, width = mosaic_shape if valid_shape is None else valid_shape
    height, width = jnp.asarray(height, jnp.int32), jnp.asarray(width, jnp.int32)
    rows = 2 * jax.lax.broadcasted_iota(jnp.int32, mosaic_shape, 0) - (height - 1)
    cols = 2 * jax.lax.broadcasted_iota(jnp.int32, mosaic_shape, 1) - (width - 1)
    squared_diagonal = (height - 1) * (height - 1) + (width - 1) * (width - 1)
    return (rows * rows + cols * cols).astype(dtype) / jnp.maximum(squared_diagonal, 1).astype(dtype)


def radial_distance_squared(plane_shape, dtype=jnp.float32):
    """r^2 of every full-mosaic pixel, as planes (4, H/2, W/2); r = 1 in the corners."""
    half_h, half_w = plane_shape
    return to_planes(radial_distance_squared_mosaic((2 * half_h, 2 * half_w), dtype))


def shading_gain_mosaic(mosaic_shape, shading, dtype=jnp.float32, *, valid_shape=None):
    """Radial gain 1 + a1[p] r^2 + a2[p] r^4 of every pixel (H, W) (`valid_shape`: see
    `radial_distance_squared_mosaic`)."""
    r2 = radial_distance_squared_mosaic(mosaic_shape, dtype, valid_shape=valid_shape)
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

def apply_optical_effects(mosaic, effects: SensorEffects, *, valid_shape=None):
    """Effects on the light reaching each pixel: lens/colour shading and per-channel gain.
    `valid_shape`: (h, w) of the image in the top-left of a zero-padded mosaic."""
    gain = shading_gain_mosaic(mosaic.shape, effects.shading, mosaic.dtype, valid_shape=valid_shape)
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
