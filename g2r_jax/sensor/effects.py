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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from g2r_jax.sensor.layout import per_position, radial_distance_squared_mosaic


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


def changes_nothing(effects: SensorEffects) -> bool:
    """Whether `effects` (concrete values, not traced) equal `no_effects()`: no pedestal,
    clipping at 1, unit gains, no shading, defects or banding. Rendering with such effects gives
    the bytes of rendering without them (multiplying by exactly 1 and adding exactly 0 change
    no value, and clipping at 1 is where the levels clip anyway), so a caller can compile the
    pipeline without them: traced as arguments, they cost about 5x the rest of the pixel loop on
    a CPU (docs/pages/validation/performance.md)."""
    values = lambda field: np.asarray(getattr(effects, field), np.float64)
    return (not np.any(values("black_pedestal")) and float(values("clip_level")) == 1.0
            and bool(np.all(values("channel_gain") == 1.0)) and not np.any(values("shading"))
            and values("defect_rows").size == 0 and float(values("row_noise_std")) == 0.0
            and float(values("column_noise_std")) == 0.0)


def shading_gain_mosaic(mosaic_shape, shading, dtype=jnp.float32, *, valid_shape=None):
    """Radial gain 1 + a1[p] r^2 + a2[p] r^4 of every pixel (H, W) (`valid_shape`: see
    `radial_distance_squared_mosaic`)."""
    r2 = radial_distance_squared_mosaic(mosaic_shape, dtype, valid_shape=valid_shape)
    coefficients = per_position(shading, mosaic_shape)
    return 1.0 + coefficients[..., 0] * r2 + coefficients[..., 1] * r2**2


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
