"""CFA site planes of a Bayer mosaic and the spread of their block means: the structure test that
tells pure noise (a dark frame, a frame minus its burst's median) from a scene.

Block means of `BLOCK` x `BLOCK` pixels of pure noise of sd s spread by s / BLOCK (the standard
error of a mean of BLOCK^2 independent values); a scene's texture spreads them far more.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.measure.robust import iqr_sd

SITES = ((0, 0), (0, 1), (1, 0), (1, 1))   # CFA tile positions, row-major in the 2 x 2 tile
BLOCK = 8


def site_planes(mosaic, dtype=np.float64) -> list:
    """The four CFA site planes of `mosaic` (H, W) (even size, a trailing row/column dropped)."""
    m = np.asarray(mosaic)
    h, w = m.shape[0] // 2 * 2, m.shape[1] // 2 * 2
    return [m[dy:h:2, dx:w:2].astype(dtype) for dy, dx in SITES]


def block_means(plane, size: int = BLOCK) -> np.ndarray:
    """(h // size, w // size) means of non-overlapping size x size blocks (edges trimmed)."""
    plane = np.asarray(plane)
    h, w = plane.shape[0] // size * size, plane.shape[1] // size * size
    return plane[:h, :w].reshape(h // size, size, w // size, size).mean(axis=(1, 3))


def block_spread(plane, size: int = BLOCK) -> float:
    """Robust sd (`iqr_sd`) of the plane's block means: at most a few times sd / size for noise."""
    return iqr_sd(block_means(plane, size))
