"""Lossless JPEG tiles of a Bayer mosaic, the DNG raw compression (Compression 7).

DNG stores compressed CFA data as lossless JPEG (ITU T.81 Annex H, process 14; DNG spec 1.6
ch. 3 'Compression'), one JPEG stream per tile. Tiles follow TIFF 6.0 section 15: their sides are
multiples of 16, and the tiles on the right and bottom edges reach past the image; readers drop
the padding, which here repeats the last row and column so that it costs almost nothing.

A tile is never wider than the image: LibRaw (0.21) places a tile's samples by wrapping at
the tile width or at the image width, whichever comes first, so a tile wider than the image comes
out scrambled. Tiles are 256 x 256 (the Adobe DNG Converter's size), narrower for images under 256
pixels wide (the width rounded down to 16), shorter for images under 256 rows.

Each (h, w) tile is encoded as a one-component image of h/2 rows of 2w samples: two mosaic rows
per JPEG row. The encoder (liblj92 through imagecodecs' `ljpeg_encode`) uses predictor 6,
Rb + (Ra - Rc)/2; in this layout Rb, the sample above, lies two mosaic rows up, the same colour,
where in the plain (h, w) layout it would be another colour. Readers map a tile's decoded samples
to the tile in row-major order whatever the JPEG's width (LibRaw, the Adobe DNG SDK and
tifffile all do), so the layout needs no tag. Measured on 12-MP frames of our outputs
(docs/pages/validation/performance.md): 0.37-0.51 of the uncompressed size for the 10-bit
s20fe_night profile, 0.62-0.66 for the 14-bit gopro_hero6, against 0.65-0.91 for the plain
layout.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TILE_SIDE", "encode_tiles", "precision_for", "tile_shape"]

TILE_SIDE = 256   # the tile side the Adobe DNG Converter writes; sizes within 1 % of 512 or one strip


def precision_for(mosaic: np.ndarray, white_level: float) -> int:
    """The JPEG sample precision (bits) that holds `white_level` and every value of `mosaic`;
    at least 8, the smallest liblj92 encodes."""
    largest = max(int(white_level), int(mosaic.max()) if mosaic.size else 0)
    bits = max(8, largest.bit_length())
    if bits > 16:
        raise ValueError(f"values up to {largest} do not fit 16-bit lossless JPEG")
    return bits


def tile_shape(height: int, width: int) -> tuple:
    """(TileLength, TileWidth) for an H x W mosaic: multiples of 16, at most `TILE_SIDE`, the
    width at most the image's (see the module note on LibRaw); images under 16 pixels wide get
    16 (no reader of ours takes them: LibRaw needs 22)."""
    length = min(TILE_SIDE, -(-height // 16) * 16)
    width = max(16, min(TILE_SIDE, width // 16 * 16))
    return length, width


def _tile(mosaic: np.ndarray, top: int, left: int, shape) -> np.ndarray:
    block = mosaic[top:top + shape[0], left:left + shape[1]]
    if block.shape != tuple(shape):     # an edge tile: repeat the last row/column into the padding
        block = np.pad(block, ((0, shape[0] - block.shape[0]), (0, shape[1] - block.shape[1])), mode="edge")
    return block


def encode_tiles(mosaic: np.ndarray, precision: int, shape=None) -> list:
    """The lossless JPEG streams of the tiles of an (H, W) uint16 mosaic, in TIFF order (left
    to right, then top to bottom).

    **Arguments:** `mosaic`: (H, W) uint16; `precision`: JPEG sample bits (8..16, see
    `precision_for`); `shape`: (TileLength, TileWidth), multiples of 16 (default `tile_shape`).

    **Returns:** a list of `bytes`, one JPEG stream per tile.
    """
    import imagecodecs

    mosaic = np.asarray(mosaic, np.uint16)
    height, width = mosaic.shape
    shape = tuple(shape) if shape is not None else tile_shape(height, width)
    if any(side % 16 or side < 16 for side in shape):
        raise ValueError(f"tile sides must be positive multiples of 16, got {shape}")
    streams = []
    for top in range(0, height, shape[0]):
        for left in range(0, width, shape[1]):
            block = np.ascontiguousarray(_tile(mosaic, top, left, shape)).reshape(shape[0] // 2, 2 * shape[1])
            streams.append(imagecodecs.ljpeg_encode(block, bitspersample=precision))
    return streams
