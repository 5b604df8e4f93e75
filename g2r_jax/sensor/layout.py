"""The CFA mosaic layout: tile position p = 2 * (row % 2) + (col % 2) indexes every per-channel
parameter; `per_position` picks each pixel's value, `to_planes`/`from_planes` convert to and from
the four CFA planes (4, H/2, W/2), `radial_distance_squared*` give r^2 from the image centre."""

from __future__ import annotations

import jax
import jax.numpy as jnp


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


def to_planes(mosaic):
    """(H, W) mosaic -> (4, H/2, W/2) planes in tile order (0,0), (0,1), (1,0), (1,1)."""
    height, width = mosaic.shape
    return mosaic.reshape(height // 2, 2, width // 2, 2).transpose(1, 3, 0, 2).reshape(4, height // 2, width // 2)


def from_planes(planes):
    """(4, H/2, W/2) planes -> (H, W) mosaic (inverse of `to_planes`)."""
    _, half_h, half_w = planes.shape
    tile = planes.reshape(2, 2, half_h, half_w)
    return tile.transpose(2, 0, 3, 1).reshape(2 * half_h, 2 * half_w)
