"""Evidence inside one file: statistics over the thousands of regions of one mosaic, with
intervals, and the two disjoint halves of those regions (fit on one, test on the other).

Regions are square tiles of the CFA planes laid out as a checkerboard (`TILE` plane pixels, a
multiple of the noise estimator's 8-pixel blocks, so no block straddles two tiles). The tiles of
one colour of the checkerboard form half "A", the others half "B"; each half is gathered into a
compact (4, n * TILE, TILE) stack that the estimators read like any plane (blocks never cross a
tile border), and at most `MAX_TILES` tiles per half are used, chosen evenly over the image, so a
12-MP file costs about as much as a 2-MP one.

The noise level function per CFA position comes from `g2r_jax.sensor.noise.estimation` (Foi et al.
2008's flat-block method with bootstrap intervals) when that module is present, else from
`_block_nlf` below, a smaller version of the same method (white noise only).
"""

from __future__ import annotations

import numpy as np

TILE = 64
MAX_TILES = 160
MIN_TILES = 40
N_BINS = 16
SMALL_MIN_BLOCKS = 10


def tile_size(plane_shape) -> int:
    """TILE, or for small planes a smaller multiple of 8 so that there are at least ~8 tiles a side."""
    return int(min(TILE, max(16, min(plane_shape) // 8 // 8 * 8)))


def tile_halves(planes, *, tile: int | None = None, max_tiles: int = MAX_TILES):
    """(A, B): the two checkerboard halves of the tiles of `planes` (4, h, w), each a
    (4, n * tile, tile) stack of at most `max_tiles` tiles spread evenly over the image."""
    _, h, w = planes.shape
    tile = tile or tile_size((h, w))
    ny, nx = h // tile, w // tile
    halves = []
    for parity in (0, 1):
        cells = [(i, j) for i in range(ny) for j in range(nx) if (i + j) % 2 == parity]
        if len(cells) > max_tiles:
            cells = [cells[k] for k in np.linspace(0, len(cells) - 1, max_tiles).round().astype(int)]
        if not cells:
            halves.append(np.zeros((planes.shape[0], 0, tile)))
            continue
        halves.append(np.concatenate([planes[:, i * tile:(i + 1) * tile, j * tile:(j + 1) * tile]
                                      for i, j in cells], axis=1))
    return tuple(halves)


def nlf_edges(n_bins: int = N_BINS) -> np.ndarray:
    """Signal bin edges: geometric from 2^-11 to 1, plus one bin below for the dark floor."""
    return np.concatenate([[-np.inf], np.geomspace(2.0**-11, 1.0, n_bins)])


def noise_level_function(planes, *, clip, clip_low, edges=None, seed: int = 0, min_blocks: int = 30):
    """Measured NLF of (4, h, w) planes (or their `noise_estimation.block_statistics`) with 95 % intervals: an object with (4, B) `signal`,
    `variance`, `lower`, `upper`, `counts`: a `noise_estimation.NoiseLevelEstimate`."""
    edges = nlf_edges() if edges is None else edges
    clip = np.broadcast_to(np.asarray(clip, np.float64), (4,))
    clip_low = np.broadcast_to(np.asarray(clip_low, np.float64), (4,))
    from g2r_jax.sensor.noise import estimation as noise_estimation

    return noise_estimation.estimate_noise_level_function(planes, clip=clip, clip_low=clip_low, edges=edges,
                                                         seed=seed, min_blocks=min_blocks)


def quantisation_variance(black_level, white_level) -> np.ndarray:
    """(4,) variance of rounding to integer DN, 1/12 DN^2 (Widrow & Kollar, *Quantization Noise*,
    2008, ch. 4), in normalised units per position."""
    span = float(white_level) - np.resize(np.asarray(black_level, np.float64), 4)
    return 1.0 / 12.0 / span**2


def tiles_per_half(n_files: int) -> int:
    """Tiles per half for a set of `n_files` large files: MAX_TILES for up to 4 files, then fewer
    (at least MIN_TILES), so that the set's total stays near 4 * MAX_TILES: the noise test pools
    the files (and with 3 or more, its standard error is at least their between-file spread), so
    24 files need no more regions each than 4 do."""
    return int(np.clip(4 * MAX_TILES // max(n_files, 1), MIN_TILES, MAX_TILES))


def nlf_halves(planes, *, clip, clip_low, seed: int = 0, max_tiles: int = MAX_TILES) -> dict:
    """{"A", "B", "all"}: the NLF measured on each checkerboard half of the tiles and on both
    (the blocks' statistics computed once).
    Bins: up to N_BINS, fewer for small files (about 150 blocks of 8 x 8 per bin and plane); a
    bin needs SMALL_MIN_BLOCKS kept blocks in files with fewer than 3000 blocks per plane (their
    power comes from pooling files), 30 otherwise."""
    from g2r_jax.sensor.noise.estimation import block_statistics

    a, b = tile_halves(planes, max_tiles=max_tiles)
    blocks = (a.shape[1] * a.shape[2] + b.shape[1] * b.shape[2]) / 64
    edges = nlf_edges(int(np.clip(blocks / 150, 6, N_BINS)))
    least = 30 if blocks >= 3000 else SMALL_MIN_BLOCKS
    a, b = block_statistics(a), block_statistics(b)   # once; "all" is both halves' blocks together
    both = a.concatenate(b)
    options = dict(clip=clip, clip_low=clip_low, edges=edges, min_blocks=least)
    return {"A": noise_level_function(a, seed=seed, **options),
            "B": noise_level_function(b, seed=seed + 1, **options),
            "all": noise_level_function(both, seed=seed + 2, **options)}
