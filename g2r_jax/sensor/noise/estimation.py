"""Noise of one raw mosaic, measured from its own pixels: the noise level function per CFA channel
(variance against signal) with confidence intervals, and the noise's spatial correlation.

The method is the single-image approach of Foi, Trimeche, Katkovnik & Egiazarian, "Practical
Poissonian-Gaussian noise modeling and fitting for single-image raw-data", IEEE TIP 17(10), 2008:
local noise estimates on smooth regions, grouped into level sets (signal bins), robust to
texture and edges. Here the local estimates are small blocks of each CFA plane (8 x 8 plane
pixels by default, i.e. 16 x 16 mosaic pixels):

1. In every block a plane a + b y + c x is fitted by least squares and removed (the block's
   smooth signal, gradients included); the residual's empirical autocovariance is taken at the 13
   lags of a half 5 x 5 window (`LAGS`).
2. Blocks are grouped by their mean signal (bins). Texture and edges can only add variance, so in
   each bin blocks whose residual energy or low-frequency energy lies above a quantile of its
   distribution for noise alone are discarded, iterated to a fixed point, and the kept blocks'
   mean corrected for the truncation (`_robust_mean_statistics`; quantiles LEVEL_QUANTILES for
   the level function, KEEP_QUANTILE and KEEP_QUANTILE_LOW for the correlation).
3. Removing the fitted plane biases the empirical autocovariances by a known linear map of the
   true ones (E[e e^T] = R Sigma R with R = I - P the residual projection). With the noise's
   autocovariance assumed zero beyond lag 2 (a 3 x 3 correlation kernel or white noise), the 13
   mean block statistics of a bin determine the 13 true autocovariances exactly
   (`_bias_matrix`): the pixel variance C(0,0) and the correlations, unbiased for white and for
   short-range correlated noise alike. (For white noise this reduces to the usual (n - 3)
   degrees-of-freedom correction.)
4. Confidence intervals: percentile bootstrap over the kept blocks of the bin (Efron &
   Tibshirani 1993, ch. 13); blocks do not overlap and the noise is short-range, so blocks are
   independent samples.

Bins whose signal range comes within `EDGE_SIGMAS` noise standard deviations of a clipping level
(the black clip at 0 DN when the black level is small, the white clip) are left out: clipping
removes variance there.

Public API (numpy, not jitted; analysis, not the simulation core):
- `estimate_noise_level_function(planes, ...) -> NoiseLevelEstimate`
- `block_statistics(planes, ...) -> BlockStatistics`: step 1 once, for several estimates
- `estimate_noise_correlation(planes, ...) -> NoiseCorrelationEstimate`
- `checkerboard_regions(plane_shape, tile)`: two complementary region masks (fit / held out)
- `quantisation_variance(black_level, white_level)`: 1/12 DN^2 in normalised units
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache

import numpy as np
from scipy import special as _special

from g2r_jax.sensor.noise.quantisation import rounding_variance as quantisation_variance   # 1/12 DN^2, normalised

# Unique lags (dy, dx) of a half 5 x 5 window: the support of the autocovariance of noise
# correlated by a 3 x 3 kernel (C(-l) = C(l)).
LAGS = ((0, 0), (0, 1), (0, 2), (1, -2), (1, -1), (1, 0), (1, 1), (1, 2),
        (2, -2), (2, -1), (2, 0), (2, 1), (2, 2))
BLOCK = 8
KEEP_QUANTILE = 0.999
KEEP_QUANTILE_LOW = 0.99
# The level function's selection: tighter, because weak texture (an edge of a few noise standard
# deviations) passes the correlation's looser one and raises the variance; see `_robust_mean_statistics`.
LEVEL_QUANTILES = (0.95, 0.95)
EDGE_SIGMAS = 4.0
MIN_BLOCKS = 30
N_BOOTSTRAP = 200

LARGE = 4_000_000          # mosaics with more pixels are held in float32 (half the memory traffic)


def to_normalised_planes(mosaic, black_level, white_level) -> np.ndarray:
    """(H, W) DN mosaic -> (4, H/2, W/2) planes x = (DN - black) / (white - black); float64,
    float32 above `LARGE` pixels."""
    m = np.asarray(mosaic)
    dtype = np.float32 if m.size > LARGE else np.float64
    black = np.resize(np.asarray(black_level, np.float64), 4)
    scale = 1.0 / (float(white_level) - black)
    return np.stack([(m[dy::2, dx::2].astype(dtype) - dtype(black[p])) * dtype(scale[p])     # sensor.to_planes
                     for p, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1)))])


@dataclasses.dataclass(frozen=True)
class NoiseLevelEstimate:
    """Measured noise level function per CFA tile position p (row-major in the 2 x 2 tile).

    Arrays are (4, B) over B signal bins (NaN where a bin has too few flat blocks or is near a
    clipping level), in normalised units x = (DN - BlackLevel) / (WhiteLevel - BlackLevel):
    - `edges` (B + 1,): the bin edges (mean block signal).
    - `signal`: mean signal of the kept blocks of the bin (where to read the variance).
    - `variance`: the pixel noise variance, corrected for the block detrending and for short-range
      correlation; `lower`, `upper`: its bootstrap confidence interval (`confidence`).
    - `counts`: kept blocks; `rejected`: blocks of the bin discarded as textured.
    - `autocovariance` (4, B, 13): the noise autocovariance at `LAGS` (index 0 = `variance`).
    """

    edges: np.ndarray
    signal: np.ndarray
    variance: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    counts: np.ndarray
    rejected: np.ndarray
    autocovariance: np.ndarray
    confidence: float
    block: int

    def valid(self) -> np.ndarray:
        """(4, B) True where the bin has an estimate."""
        return np.isfinite(self.variance)

    def as_dict(self) -> dict:
        """JSON-ready summary (lists; NaN as None)."""
        clean = lambda a: [[None if not np.isfinite(v) else float(v) for v in row] for row in np.asarray(a)]
        return {"edges": np.asarray(self.edges).tolist(), "signal": clean(self.signal),
                "variance": clean(self.variance), "lower": clean(self.lower), "upper": clean(self.upper),
                "counts": np.asarray(self.counts).tolist(), "confidence": self.confidence, "block": self.block}


@dataclasses.dataclass(frozen=True)
class NoiseCorrelationEstimate:
    """Normalised autocorrelation rho(dy, dx) = C(dy, dx) / C(0, 0) of the noise per tile position.

    - `lags`: the 13 `LAGS`; `rho` (4, 13) with `lower`/`upper` bootstrap intervals (rho[:, 0] = 1).
    - `neighbour` (4, 3): rho at the lags (0, 1), (1, 0), (1, 1) (within each CFA plane), the
      quick answer to "is it white?"; `neighbour_lower`/`neighbour_upper` their intervals.
    - `white` (4,): True unless some lag's rho differs from 0 at level 1 - `confidence`, with
      Bonferroni's correction over the 12 lags (z from the bootstrap standard deviation `sd`).
    - `blocks` (4,): blocks used.
    """

    lags: tuple
    rho: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    sd: np.ndarray
    blocks: np.ndarray
    confidence: float

    @property
    def neighbour(self) -> np.ndarray:
        return self.rho[:, [LAGS.index((0, 1)), LAGS.index((1, 0)), LAGS.index((1, 1))]]

    @property
    def neighbour_lower(self) -> np.ndarray:
        return self.lower[:, [LAGS.index((0, 1)), LAGS.index((1, 0)), LAGS.index((1, 1))]]

    @property
    def neighbour_upper(self) -> np.ndarray:
        return self.upper[:, [LAGS.index((0, 1)), LAGS.index((1, 0)), LAGS.index((1, 1))]]

    @property
    def white(self) -> np.ndarray:
        from scipy.stats import norm

        z = norm.ppf(1 - (1 - self.confidence) / 2 / (len(self.lags) - 1))
        return np.all(np.abs(self.rho[:, 1:]) <= z * self.sd[:, 1:], axis=1)

    def autocorrelation_window(self, p: int) -> np.ndarray:
        """The full 5 x 5 autocorrelation of position p (centre = lag 0), symmetric."""
        return _window(self.rho[p])

    def as_dict(self) -> dict:
        return {"lags": [list(l) for l in self.lags], "rho": self.rho.tolist(), "lower": self.lower.tolist(),
                "upper": self.upper.tolist(), "sd": self.sd.tolist(), "white": self.white.tolist(), "blocks": self.blocks.tolist(),
                "confidence": self.confidence}


def _window(values) -> np.ndarray:
    window = np.zeros((5, 5))
    for (dy, dx), v in zip(LAGS, values):
        window[2 + dy, 2 + dx] = v
        window[2 - dy, 2 - dx] = v
    return window


def default_edges(n_bins: int = 16, low: float = 2.0**-11, high: float = 1.0) -> np.ndarray:
    """Geometric signal bins from `low` to `high`, with one more bin [-inf, low) for the dark floor."""
    return np.concatenate([[-np.inf], np.geomspace(low, high, n_bins)])


def checkerboard_regions(plane_shape, tile: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Two complementary (h, w) masks of a plane: tile x tile squares in a checkerboard. Fit on
    one half of the regions, test on the other (issue 9's within-file hold-out)."""
    h, w = plane_shape
    ty, tx = np.arange(h)[:, None] // tile, np.arange(w)[None, :] // tile
    first = (ty + tx) % 2 == 0
    return first, ~first


# ---------------------------------------------------------------------------- block statistics

@lru_cache(maxsize=8)
def _residual_projection(block: int) -> np.ndarray:
    """R = I - P, P the least-squares projection on span{1, y, x} over a block x block block."""
    y, x = np.mgrid[0:block, 0:block]
    design = np.stack([np.ones(block * block), y.ravel() - (block - 1) / 2, x.ravel() - (block - 1) / 2], 1)
    projection = design @ np.linalg.solve(design.T @ design, design.T)
    return np.eye(block * block) - projection


def _lag_pairs(block: int, dy: int, dx: int):
    """Flat indices (i, j) of the pixel pairs at offset (dy, dx) inside a block."""
    y, x = np.mgrid[0:block, 0:block]
    y2, x2 = y + dy, x + dx
    ok = (y2 >= 0) & (y2 < block) & (x2 >= 0) & (x2 < block)
    return (y * block + x)[ok], (y2 * block + x2)[ok]


@lru_cache(maxsize=8)
def _bias_matrix(block: int) -> np.ndarray:
    """A (13, 13): E[block lag statistics] = A @ true autocovariances (at `LAGS`, zero beyond).

    For true autocovariance at lag l only, Sigma_l has ones at pixel pairs offset by +-l; the
    residual covariance is R Sigma_l R; the statistic at lag k averages it over the pairs of k."""
    n = block * block
    residual = _residual_projection(block)
    pairs = [_lag_pairs(block, dy, dx) for dy, dx in LAGS]
    matrix = np.zeros((len(LAGS), len(LAGS)))
    for column, (i, j) in enumerate(pairs):
        sigma = np.zeros((n, n))
        sigma[i, j] = 1.0
        sigma[j, i] = 1.0
        covariance = residual @ sigma @ residual
        for row, (a, b) in enumerate(pairs):
            matrix[row, column] = covariance[a, b].mean()
    return matrix


@lru_cache(maxsize=8)
def _low_frequency_basis(block: int) -> np.ndarray:
    """(n, 11) orthonormal shapes that an edge or a curved surface puts energy into, orthogonal
    to the fitted plane: y^2, x^2, xy, and steps across the block at 1/4, 1/2 and 3/4 of its
    height and width and along both diagonals."""
    y, x = np.mgrid[0:block, 0:block]
    y, x = (y.ravel() - (block - 1) / 2) / block, (x.ravel() - (block - 1) / 2) / block
    shapes = [y * y, x * x, x * y, np.sign(x + y + 1e-9), np.sign(x - y + 1e-9)]
    shapes += [np.sign(v - t + 1e-9) for v in (y, x) for t in (-0.25, 0.0, 0.25)]
    q, _ = np.linalg.qr(_residual_projection(block) @ np.stack(shapes, 1))
    return q


def _blocks(plane: np.ndarray, block: int, region: np.ndarray | None):
    """(N, block*block) pixels of the non-overlapping blocks fully inside `region`."""
    h, w = plane.shape
    h, w = h - h % block, w - w % block
    tiles = plane[:h, :w].reshape(h // block, block, w // block, block).transpose(0, 2, 1, 3)
    tiles = tiles.reshape(-1, block * block)
    if region is None:
        return tiles
    inside = region[:h, :w].reshape(h // block, block, w // block, block).all(axis=(1, 3)).reshape(-1)
    return tiles[inside]


def _block_statistics(tiles: np.ndarray, block: int):
    """Per block: mean, max, min signal and (N, 14) statistics: the 13 residual lag statistics
    and the residual's energy in the low-frequency shapes (`_low_frequency_basis`)."""
    residual = tiles @ _residual_projection(block)
    square = residual.reshape(-1, block, block)
    stats = np.empty((tiles.shape[0], len(LAGS) + 1))
    for k, (dy, dx) in enumerate(LAGS):
        # the pixel pairs at offset (dy, dx) inside a block, as two overlapping windows
        first = square[:, :block - dy, max(0, -dx):block - max(0, dx)]
        second = square[:, dy:, max(0, dx):block + min(0, dx)]
        stats[:, k] = np.einsum("nij,nij->n", first, second) / first[0].size
    stats[:, -1] = np.einsum("nk,nk->n", low := residual @ _low_frequency_basis(block), low)
    return tiles.mean(axis=1), tiles.max(axis=1), tiles.min(axis=1), stats


@lru_cache(maxsize=8)
def _lag_indicators(block: int) -> np.ndarray:
    """(13, n, n): S_l with ones at the pixel pairs offset by +-l (identity for lag 0)."""
    n = block * block
    out = np.zeros((len(LAGS), n, n))
    for k, (dy, dx) in enumerate(LAGS):
        i, j = _lag_pairs(block, dy, dx)
        out[k, i, j] = 1.0
        out[k, j, i] = 1.0
    return out


@lru_cache(maxsize=8)
def _quadratic_form_tables(block: int):
    """Traces that make `_quadratic_form_moments` a few dot products: with Sigma = sum_l c_l S_l,
    tr(R Sigma R) = c . t and tr((R Sigma R)^2) = c^T G c (likewise for the low-frequency
    shapes B^T Sigma B), t and G precomputed from the lag indicators S_l."""
    residual, basis = _residual_projection(block), _low_frequency_basis(block)
    indicators = _lag_indicators(block)
    m = np.einsum("ij,ljk,km->lim", residual, indicators, residual)
    low = np.einsum("ji,ljk,km->lim", basis, indicators, basis)
    tables = []
    for a in (m, low):
        flat = a.reshape(len(LAGS), -1)
        tables.append((np.trace(a, axis1=1, axis2=2), flat @ flat.T, a.shape[1]))
    return tuple(tables)


def _quadratic_form_moments(autocovariance: np.ndarray, block: int):
    """(mean, degrees of freedom) of n s0 = e^T e and of the low-frequency energy under noise of
    this autocovariance: e ~ N(0, M), M = R Sigma R, so each is a weighted chi-square, matched
    by a scaled chi-square with k = tr(M)^2 / tr(M^2) (Satterthwaite, Biometrics Bulletin 1946)."""
    c = np.asarray(autocovariance, np.float64)
    out = []
    for trace, gram, size in _quadratic_form_tables(block):
        mean, square = np.float64(c @ trace), np.float64(c @ gram @ c)   # numpy floats: x / 0 -> inf, as before
        out.append((mean, float(np.clip(mean**2 / max(square, 1e-300), 1.0, size))))
    return tuple(out)


def _chi2_ppf(q, k):
    """Quantile of chi-square(k): 2 P^-1(k/2, q), P the regularised lower incomplete gamma
    function (what scipy.stats.chi2.ppf computes, without its per-call overhead)."""
    return 2.0 * _special.gammaincinv(0.5 * k, q)


def _chi2_cdf(x, k):
    return _special.gammainc(0.5 * k, 0.5 * x)


def _robust_mean_statistics(stats: np.ndarray, block: int, iterations: int = 40,
                            quantiles: tuple[float, float] = (KEEP_QUANTILE, KEEP_QUANTILE_LOW)):
    """(kept mask, mean lag statistics corrected for the truncation) of one bin's blocks.

    Texture and edges only add variance, so clean blocks form the lower part of the block
    statistics. Iterated truncation, as the weak-texture patch selection of Liu, Tanaka &
    Okutomi ("Single-image noise level estimation for blind denoising", IEEE TIP 2013): keep
    blocks whose residual energy n s0 and whose low-frequency energy (edges, curvature) are both
    below the KEEP_QUANTILE of their distribution for noise alone at the current estimate
    (scaled chi-squares with the effective degrees of freedom of that noise), re-estimate from
    the kept blocks, repeat. It starts low (from the 10th percentile of s0) and rises to the
    fixed point; the truncated mean is corrected by E[X | X < q] = F_{k+2}(q) / F_k(q) E[X] for
    X ~ chi2_k (Johnson, Kotz & Balakrishnan, Continuous Univariate Distributions 1, ch. 18).

    `quantiles` (energy, low-frequency energy): the noise correlation keeps the default (0.999,
    0.99), where the common correction of all 13 lag means is accurate (at 0.95 it reads white
    noise as correlated, since truncating on the low-frequency energy shifts the lag products
    unequally); the level function uses LEVEL_QUANTILES (0.95, 0.95), whose variance stays
    unbiased on flat patches (median measured / true x1.00 on s20fe_night and demo simulations at
    ISO 106-3170) and holds less texture: on single 1000 x 1500 dead-leaves files at ISO
    1700-3200 the median bias fell from x1.10-1.12 to x1.03-1.05.
    """
    keep_quantile, keep_quantile_low = quantiles
    n = block * block
    energy, low = stats[:, 0] * n, stats[:, -1]
    c = np.zeros(len(LAGS))
    c[0] = np.quantile(stats[:, 0], 0.1) / (_chi2_ppf(0.1, n - 3) / (n - 3)) * n / (n - 3)
    keep = np.ones(len(energy), bool)
    mean = stats[:, :-1].mean(axis=0)
    for _ in range(iterations):
        (mean_energy, k), (mean_low, k_low) = _quadratic_form_moments(c, block)
        q, q_low = _chi2_ppf(keep_quantile, k), _chi2_ppf(keep_quantile_low, k_low)
        new_keep = (energy <= mean_energy * q / k) & (low <= mean_low * q_low / k_low)
        if new_keep.sum() < 2:
            keep = new_keep
            break
        # expected fraction of the energy kept by each truncation (the low-frequency part is
        # mean_low / mean_energy of the total)
        share = mean_low / mean_energy
        kept_fraction = (_chi2_cdf(q, k + 2) / keep_quantile) * (
            1 - share + share * _chi2_cdf(q_low, k_low + 2) / keep_quantile_low)
        mean = stats[new_keep, :-1].mean(axis=0) / kept_fraction
        new_c = _solve(mean, block)
        if new_c[0] <= 0:
            keep = new_keep
            break
        converged = np.array_equal(new_keep, keep) and abs(new_c[0] - c[0]) <= 1e-6 * c[0]
        keep, c = new_keep, new_c
        if converged:
            break
    return keep, mean


def _bootstrap_means(samples: np.ndarray, n_bootstrap: int, rng) -> np.ndarray:
    """(n_bootstrap, k) means of samples (N, k) resampled with replacement."""
    n = len(samples)
    draws = rng.integers(0, n, (n_bootstrap, n)) + n * np.arange(n_bootstrap)[:, None]
    weights = np.bincount(draws.ravel(), minlength=n_bootstrap * n).reshape(n_bootstrap, n)
    return weights @ samples / n


def _solve(mean_stats, block: int) -> np.ndarray:
    return np.linalg.solve(_bias_matrix(block), np.asarray(mean_stats).T).T


def _per_position(value, default) -> np.ndarray:
    return np.resize(np.asarray(default if value is None else value, np.float64), 4)


@dataclasses.dataclass(frozen=True)
class BlockStatistics:
    """The per-block quantities the estimators start from, per CFA position p: `mean`, `top`,
    `bottom` (N_p,) signal of each 8 x 8 block and `stats` (N_p, 14) (`_block_statistics`).
    Computed once (`block_statistics`), they serve several estimates: the two halves of a file's
    regions and, concatenated (`concatenate`), both together."""

    mean: tuple
    top: tuple
    bottom: tuple
    stats: tuple
    block: int

    def concatenate(self, *others: "BlockStatistics") -> "BlockStatistics":
        parts = (self,) + others
        join = lambda name: tuple(np.concatenate([getattr(b, name)[p] for b in parts]) for p in range(len(self.mean)))
        return BlockStatistics(mean=join("mean"), top=join("top"), bottom=join("bottom"), stats=join("stats"),
                               block=self.block)


def block_statistics(planes, *, block: int = BLOCK, region=None) -> BlockStatistics:
    """Block statistics of (P, h, w) planes (blocks fully inside `region` when given), for
    `estimate_noise_level_function` / `estimate_noise_correlation` in place of the planes."""
    columns = [_block_statistics(_blocks(np.asarray(plane, np.float64), block, region), block) for plane in planes]
    return BlockStatistics(*(tuple(c[k] for c in columns) for k in range(4)), block=block)


def _bin_blocks(planes, *, block, edges, clip, clip_low, region):
    """For each position: block means, statistics (N, 14), and each block's bin index (-1: none).
    `planes`: (P, h, w) planes or their `BlockStatistics`."""
    found = planes if isinstance(planes, BlockStatistics) else block_statistics(planes, block=block, region=region)
    out = []
    for p, (mean, top, bottom, stats) in enumerate(zip(found.mean, found.top, found.bottom, found.stats)):
        unclipped = (top < clip[p]) & (bottom > clip_low[p])
        index = np.searchsorted(edges, mean, side="right") - 1
        index[~unclipped | (mean >= edges[-1])] = -1
        out.append((mean, stats, index))
    return out


def _local_scale(mean, signal_row, variance_row):
    """Per block: predicted variance at the bin's signal / at the block's own mean, from the
    first pass's level function (piecewise linear in log-log, extended beyond the end bins with
    their end slopes, clipped to [0, 2]; slope 1 (shot noise) with a single bin), so that blocks
    across a bin's width pool as if read at one signal."""
    ok = np.isfinite(variance_row) & (signal_row > 0) & (variance_row > 0)
    xs, ys = np.log(signal_row[ok]), np.log(variance_row[ok])
    order = np.argsort(xs)
    xs, ys = xs[order], ys[order]
    if len(xs) == 0:
        return lambda m, at: np.ones_like(m)
    if len(xs) == 1:
        first_slope = last_slope = 1.0
    else:
        first_slope = np.clip((ys[1] - ys[0]) / (xs[1] - xs[0]), 0.0, 2.0)
        last_slope = np.clip((ys[-1] - ys[-2]) / (xs[-1] - xs[-2]), 0.0, 2.0)

    def curve(s):
        u = np.log(np.maximum(s, 1e-6))
        inside = np.interp(u, xs, ys)
        return np.exp(np.where(u < xs[0], ys[0] + first_slope * (u - xs[0]),
                               np.where(u > xs[-1], ys[-1] + last_slope * (u - xs[-1]), inside)))

    return lambda m, at: curve(at) / curve(m)


def _planes_or_blocks(planes, block, region) -> BlockStatistics:
    if isinstance(planes, BlockStatistics):
        if planes.block != block or region is not None:
            raise ValueError("block statistics were computed for another block size or without this region")
        return planes
    return block_statistics(planes, block=block, region=region)


@dataclasses.dataclass
class _Bin:
    signal: float
    stats: np.ndarray        # kept blocks' lag statistics (N, 13), rescaled to `signal`
    correction: np.ndarray   # (13,) truncation correction of their mean
    autocovariance: np.ndarray
    rejected: int


def _measure_bins(planes, *, clip, clip_low, edges, block, region, min_blocks,
                  quantiles=(KEEP_QUANTILE, KEEP_QUANTILE_LOW)):
    """Per position, per bin: a `_Bin` (or None). Two passes: the first gives a rough level
    function, the second rescales every block to its bin's mean signal along it (a bin spans a
    factor 1.6 in signal, so up to 1.6 in variance) and selects and averages again."""
    n = len(edges) - 1
    result = []
    for p, (mean, stats, index) in enumerate(_bin_blocks(planes, block=block, edges=edges, clip=clip,
                                                         clip_low=clip_low, region=region)):
        signal_row, variance_row = np.full(n, np.nan), np.full(n, np.nan)
        for b in range(n):
            chosen = index == b
            if chosen.sum() >= min_blocks:
                keep, mean_stats = _robust_mean_statistics(stats[chosen], block, quantiles=quantiles)
                if keep.sum() >= min_blocks:
                    signal_row[b] = mean[chosen][keep].mean()
                    variance_row[b] = _solve(mean_stats, block)[0]
        scale = _local_scale(mean, signal_row, variance_row)
        bins = []
        for b in range(n):
            chosen = index == b
            if not np.isfinite(variance_row[b]):
                bins.append(None)
                continue
            s = stats[chosen] * scale(mean[chosen], signal_row[b])[:, None]
            keep, mean_stats = _robust_mean_statistics(s, block, quantiles=quantiles)
            if keep.sum() < min_blocks:
                bins.append(None)
                continue
            kept = s[keep, :-1]
            c = _solve(mean_stats, block)
            sd = np.sqrt(max(c[0], 0.0))
            near_clip = (edges[b + 1] + EDGE_SIGMAS * sd > clip[p]) or (edges[b] - EDGE_SIGMAS * sd < clip_low[p])
            if c[0] <= 0 or near_clip:
                bins.append(None)
                continue
            bins.append(_Bin(signal=float(signal_row[b]), stats=kept,
                             correction=mean_stats / kept.mean(axis=0), autocovariance=c,
                             rejected=int((~keep).sum())))
        result.append(bins)
    return result


def estimate_noise_level_function(planes, *, clip=None, clip_low=None, edges=None, n_bins: int = 16,
                                  block: int = BLOCK, region=None, confidence: float = 0.95,
                                  n_bootstrap: int = N_BOOTSTRAP, min_blocks: int = MIN_BLOCKS,
                                  seed: int = 0) -> NoiseLevelEstimate:
    """The noise level function of one mosaic, per CFA tile position (see the module docstring).

    **Arguments:**
    - `planes`: (4, H/2, W/2) normalised planes, x = (DN - black) / (white - black)
      (`g2r_jax.audit.stats.to_normalised_planes`), or their `block_statistics` (computed once
      for several estimates).
    - `clip`: (4,) or scalar normalised white clip (default 1.0): blocks reaching it are left out.
    - `clip_low`: (4,) or scalar normalised value of raw DN 0, i.e. -black / (white - black)
      (default -inf: no black clip); a DNG with BlackLevel 0 has 0 here.
    - `edges`: signal bin edges (default `default_edges(n_bins)`).
    - `block`: block side in plane pixels; `region`: optional (H/2, W/2) bool mask, only blocks
      fully inside it count (e.g. one half of `checkerboard_regions`).
    - `confidence`, `n_bootstrap`, `seed`: the bootstrap intervals; `min_blocks`: fewest kept
      blocks for a bin to get an estimate.

    **Returns:** a `NoiseLevelEstimate`.
    """
    planes = _planes_or_blocks(planes, block, region)
    n_pos = len(planes.mean)
    clip, clip_low = _per_position(clip, 1.0), _per_position(clip_low, -np.inf)
    edges = default_edges(n_bins) if edges is None else np.asarray(edges, np.float64)
    n = len(edges) - 1
    rng = np.random.default_rng(seed)
    alpha = (1.0 - confidence) / 2
    shape = (n_pos, n)
    signal, variance, lower, upper = (np.full(shape, np.nan) for _ in range(4))
    counts, rejected = np.zeros(shape, int), np.zeros(shape, int)
    autocovariance = np.full(shape + (len(LAGS),), np.nan)
    measured = _measure_bins(planes, clip=clip, clip_low=clip_low, edges=edges, block=block, region=region,
                             min_blocks=min_blocks, quantiles=LEVEL_QUANTILES)
    for p, bins in enumerate(measured):
        for b, found in enumerate(bins):
            if found is None:
                continue
            boot = _solve(_bootstrap_means(found.stats, n_bootstrap, rng) * found.correction, block)[:, 0]
            signal[p, b], variance[p, b], autocovariance[p, b] = found.signal, found.autocovariance[0], found.autocovariance
            lower[p, b], upper[p, b] = np.quantile(boot, [alpha, 1 - alpha])
            counts[p, b], rejected[p, b] = len(found.stats), found.rejected
    return NoiseLevelEstimate(edges=edges, signal=signal, variance=variance, lower=lower, upper=upper,
                              counts=counts, rejected=rejected, autocovariance=autocovariance,
                              confidence=confidence, block=block)


def estimate_noise_correlation(planes, *, clip=None, clip_low=None, edges=None, n_bins: int = 16,
                               block: int = BLOCK, region=None, confidence: float = 0.95,
                               n_bootstrap: int = N_BOOTSTRAP, min_blocks: int = MIN_BLOCKS,
                               seed: int = 0) -> NoiseCorrelationEstimate:
    """Spatial correlation of the noise within each CFA plane, pooled over signal bins.

    Each kept block's lag statistics (selected as for `estimate_noise_level_function`) are
    divided by its bin's variance, so bright and dark blocks weigh alike, averaged over all bins,
    and mapped through the same detrending bias matrix: rho(l) = C(l) / C(0) for the 13 `LAGS`.
    White noise gives rho = 0 at every lag; denoising, lossy compression or demosaicing give
    rho > 0 at (0, 1), (1, 0), (1, 1). Intervals by bootstrap over blocks. Arguments as
    `estimate_noise_level_function`.
    """
    planes = _planes_or_blocks(planes, block, region)
    clip, clip_low = _per_position(clip, 1.0), _per_position(clip_low, -np.inf)
    edges = default_edges(n_bins) if edges is None else np.asarray(edges, np.float64)
    measured = _measure_bins(planes, clip=clip, clip_low=clip_low, edges=edges, block=block, region=region,
                             min_blocks=min_blocks)
    rng = np.random.default_rng(seed)
    alpha = (1.0 - confidence) / 2
    n_pos = len(planes.mean)
    rho, lower, upper, sd = (np.full((n_pos, len(LAGS)), np.nan) for _ in range(4))
    blocks = np.zeros(n_pos, int)
    for p, bins in enumerate(measured):
        found = [f for f in bins if f is not None]
        if not found:
            continue
        s = np.concatenate([f.stats * f.correction / f.autocovariance[0] for f in found])
        blocks[p] = len(s)
        c = _solve(s.mean(axis=0), block)
        rho[p] = c / c[0]
        boot = _solve(_bootstrap_means(s, n_bootstrap, rng), block)
        boot = boot / boot[:, :1]
        lower[p], upper[p] = np.quantile(boot, alpha, axis=0), np.quantile(boot, 1 - alpha, axis=0)
        sd[p] = boot.std(axis=0, ddof=1)
    return NoiseCorrelationEstimate(lags=LAGS, rho=rho, lower=lower, upper=upper, sd=sd, blocks=blocks,
                                    confidence=confidence)
