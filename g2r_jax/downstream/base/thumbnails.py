"""RAW mosaics and camera-RGB images -> the estimators' input: small linear camera-RGB thumbnails.

The convention is the NUS set's as republished for learned colour constancy (Cheng, Prasad,
Brown, JOSA A 2014; DMCC repository, see ../shared/data/PROVENANCE.md): black subtracted, scaled
by the range, greens of a CFA tile averaged, area-averaged to 64 x 64, every saturated pixel
zeroed (a clipped pixel carries no illuminant information; Barron, "Convolutional Color
Constancy", ICCV 2015, Sec. 5 does the same), each image scaled to a maximum of 1.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

SIZE = 64
SATURATED = 0.98   # of the range: at or above this a pixel counts as clipped


def _tile_rgb(mosaics, cfa_pattern, black_level, white_level, xp=jnp):
    """(B, H, W) DN -> (B, H/2, W/2, 3) camera RGB in [0, 1] of the range, greens averaged; `xp`
    is the array module (jax.numpy inside compiled code, numpy for one file of any size)."""
    black = xp.broadcast_to(xp.asarray(black_level, xp.float32).reshape(-1), (4,))
    span = xp.asarray(white_level, xp.float32) - black
    sites = xp.stack([(mosaics[:, i::2, j::2] - black[2 * i + j]) / span[2 * i + j]
                      for i in range(2) for j in range(2)], -1)                  # (B, H/2, W/2, 4)
    membership = (xp.asarray(cfa_pattern).reshape(4, 1) == xp.arange(3)).astype(xp.float32)   # (4, 3)
    return sites @ (membership / membership.sum(0))


def _reduce(rgb, size: int):
    """(B, h, w, 3), h and w multiples of `size` -> area average and saturation mask at size x size."""
    b, h, w, _ = rgb.shape
    blocks = rgb.reshape(b, size, h // size, size, w // size, 3)
    mean = blocks.mean((2, 4))
    clipped = jnp.any(blocks >= SATURATED, axis=(2, 4, 5))
    return jnp.where(clipped[..., None], 0.0, mean)


def _unit_max(thumbs):
    peak = jnp.max(thumbs, axis=(1, 2, 3), keepdims=True)
    return jnp.where(peak > 0, thumbs / jnp.where(peak > 0, peak, 1.0), thumbs)


@jax.jit
def mosaic_thumbnails(mosaics, cfa_pattern, black_level, white_level):
    """Mosaics (B, H, W) in DN, H/2 and W/2 multiples of 64 -> thumbnails (B, 64, 64, 3).

    **Arguments:** `cfa_pattern` (4,) colour index per tile position, `black_level` scalar or (4,),
    `white_level` scalar (a profile's fields). **Returns:** float32 thumbnails, saturated pixels 0,
    each with maximum 1.
    """
    rgb = jnp.clip(_tile_rgb(jnp.asarray(mosaics, jnp.float32), cfa_pattern, black_level, white_level), 0.0, 1.0)
    return _unit_max(_reduce(rgb, SIZE))


def area_average(image: np.ndarray, size: int) -> np.ndarray:
    """(h, w, c) -> (size, size, c): the mean over a size x size grid of blocks whose edges are
    rounded to whole pixels (numpy, any h, w >= size)."""
    h, w, _ = image.shape
    rows = np.linspace(0, h, size + 1).round().astype(int)
    cols = np.linspace(0, w, size + 1).round().astype(int)
    sums = np.add.reduceat(np.add.reduceat(image, rows[:-1], axis=0), cols[:-1], axis=1)
    return (sums / np.outer(np.diff(rows), np.diff(cols))[..., None]).astype(np.float32)


def camera_rgb_thumbnail(rgb: np.ndarray) -> np.ndarray:
    """One (h, w, 3) camera-RGB image in [0, 1] of the range, any size >= 64 x 64 -> (64, 64, 3).

    Area average over a 64 x 64 grid of blocks whose edges are rounded to whole pixels (numpy;
    for real files of any size), saturated blocks zeroed, maximum 1.
    """
    rgb = np.asarray(rgb, np.float32)
    h, w, _ = rgb.shape
    if h < SIZE or w < SIZE:
        raise ValueError(f"image of {h} x {w} is smaller than the {SIZE} x {SIZE} thumbnail")
    mean = area_average(rgb, SIZE)
    clipped = area_average((rgb >= SATURATED).any(-1, keepdims=True).astype(np.float32), SIZE)[..., 0] > 0
    thumb = np.where(clipped[..., None], 0.0, mean).astype(np.float32)
    peak = thumb.max()
    return thumb / peak if peak > 0 else thumb


def mosaic_to_camera_rgb(mosaic: np.ndarray, cfa_pattern, black_level, white_level) -> np.ndarray:
    """One mosaic (H, W) in DN -> (H/2, W/2, 3) camera RGB in [0, 1] of the range (numpy: no
    compiled program per file size)."""
    mosaic = np.asarray(mosaic)[: mosaic.shape[0] // 2 * 2, : mosaic.shape[1] // 2 * 2]
    rgb = _tile_rgb(mosaic.astype(np.float32)[None], np.asarray(cfa_pattern), black_level, white_level, xp=np)[0]
    return np.clip(rgb, 0.0, 1.0)
