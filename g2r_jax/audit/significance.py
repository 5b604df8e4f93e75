"""Two-sample tests over files: is a statistic of the measured files different from the
simulated ones? Files are the unit of resampling (pixels within a file are not independent).

- `max_t_permutation`: Welch t per component, the maximum |t| over components as the test
  statistic, its null distribution by permuting file labels (Westfall & Young, *Resampling-based
  multiple testing*, 1993: single-step maxT, which controls the family-wise error over the
  components of one statistic).
- `energy_permutation`: the two-sample energy test of Szekely & Rizzo ("Testing for equal
  distributions in high dimension", InterStat 2004; "Energy statistics", J. Stat. Plan. Inf.
  2013), permutation null.
- `consistent_outliers`: pixels flagged in many files, against a binomial chance level.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats as _scipy_stats


def _welch_t(a, b, floor):
    """Per-component Welch t of nan-aware means; `floor` (per component) is the resolution of
    the statistic, added to the standard error so that exactly repeated values (e.g. a clipping
    level in DN) do not give infinite t."""
    na, nb = np.sum(np.isfinite(a), axis=-2), np.sum(np.isfinite(b), axis=-2)
    ma, mb = np.nanmean(a, axis=-2), np.nanmean(b, axis=-2)
    va = np.nanvar(a, axis=-2, ddof=1) if a.shape[-2] > 1 else np.zeros_like(ma)
    vb = np.nanvar(b, axis=-2, ddof=1) if b.shape[-2] > 1 else np.zeros_like(mb)
    se = np.sqrt(np.nan_to_num(va) / np.maximum(na, 1) + np.nan_to_num(vb) / np.maximum(nb, 1) + floor**2)
    t = (ma - mb) / se
    return np.where((na >= 2) & (nb >= 2), t, 0.0), ma - mb


MIN_POOLED_FILES = 10   # a component enters the maxT family only with this many files that have it


def max_t_permutation(measured, simulated, *, floor=0.0, n_permutations: int = 2000, seed: int = 0) -> dict:
    """Permutation maxT test of equal means, component by component.

    **Arguments:** `measured` (n, k), `simulated` (m, k) per-file statistics (NaN = not
    available in that file); `floor`: resolution per component (scalar or (k,)).

    The family is the components available in at least MIN_POOLED_FILES files of the two sets
    together. That count does not change under permutation, so the test stays exact; a
    component seen in a handful of files (say a colour that clips in 3 measured and 2 simulated
    files) has a coarse, heavy-tailed permutation distribution of t (its SE is the floor when the
    few values repeat), could not reach a small p-value alone (the most extreme split of 9 values
    between 24 + 24 files has probability ~0.002), and would only swamp the maxT null of the
    components that carry the evidence.

    The components are put on one scale before the maximum: each |t| is divided by the 95th
    percentile of that component's own permutation distribution (which depends on the pooled
    files only, not on the labels, so the test stays a permutation test), so that one wide null
    (a clip level seen in 5 + 5 files, inside the family) no longer sets the null of the maximum
    (a mixed-size night set: p = 0.0035 with |t| = 62-82 in the greens, 0.0005 scaled). With
    comparable components this changes little; it is the studentised-by-null alternative to
    single-step minP (Westfall & Young 1993, ch. 2), which needs many more permutations for the
    same resolution.

    **Returns:** dict with `t` (k,), `difference` (k,) measured - simulated means, `p` (the
    permutation p-value of the largest scaled |t| over the family, (1 + #{perm >= obs}) / (1 + B))
    and `score` (the largest |t| over the family, unscaled).
    """
    a = np.asarray(measured, np.float64)
    b = np.asarray(simulated, np.float64)
    floor = np.broadcast_to(np.asarray(floor, np.float64), a.shape[1:])
    t, difference = _welch_t(a, b, floor)
    family = (np.sum(np.isfinite(a), 0) + np.sum(np.isfinite(b), 0)) >= MIN_POOLED_FILES
    score = float(np.max(np.abs(np.where(family, t, 0.0))))
    with np.errstate(invalid="ignore", divide="ignore"):
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            pooled = np.concatenate([a, b])
            rng = np.random.default_rng(seed)
            order = np.argsort(rng.random((n_permutations, len(pooled))), axis=1)
            shuffled = pooled[order]
            t_perm, _ = _welch_t(shuffled[:, :len(a)], shuffled[:, len(a):], floor)
    null_t = np.abs(np.nan_to_num(np.where(family, t_perm, 0.0)))
    scale = np.percentile(null_t, 95, axis=0)
    usable = family & (scale > 0)
    scale = np.where(usable, scale, 1.0)
    observed = np.max(np.where(usable, np.abs(t) / scale, 0.0))
    null = np.max(np.where(usable, null_t / scale, 0.0), axis=-1)
    p = (1 + np.sum(null >= observed)) / (1 + n_permutations)
    return {"t": t, "difference": difference, "p": float(p), "score": score}


def energy_permutation(measured, reference, *, n_permutations: int = 1000, seed: int = 0) -> dict:
    """Two-sample energy test: E = 2 E|X-Y| - E|X-X'| - E|Y-Y'| between (n, d) and (m, d)
    samples, with the permutation null (Szekely & Rizzo 2004).

    **Returns:** dict with `energy` (observed E), `p` and `score` ((E - mean null) / sd null).
    """
    x = np.asarray(measured, np.float64)
    y = np.asarray(reference, np.float64)
    pooled = np.concatenate([x, y])
    n = len(x)
    distances = np.linalg.norm(pooled[:, None] - pooled[None], axis=-1)

    m = len(pooled) - n

    def energy(labels):
        """E for each row of 0/1 labels (B, N) from the distance matrix, in one product:
        with z the indicator of sample x, sum_xy = z' D (1 - z) etc."""
        z = labels.astype(np.float64)
        zd = z @ distances
        xx = np.einsum("bn,bn->b", zd, z)
        xy = np.einsum("bn,bn->b", zd, 1 - z)
        yy = np.einsum("bn,bn->b", (1 - z) @ distances, 1 - z)
        return 2 * xy / (n * m) - xx / n**2 - yy / m**2

    observed = float(energy(np.arange(len(pooled))[None] < n)[0])
    rng = np.random.default_rng(seed)
    order = np.argsort(rng.random((n_permutations, len(pooled))), axis=1)
    null = energy(order < n)
    p = (1 + np.sum(null >= observed)) / (1 + n_permutations)
    score = (observed - null.mean()) / max(null.std(), 1e-12)
    return {"energy": float(observed), "p": float(p), "score": float(score)}


def consistent_outliers(outlier_lists, shape, *, min_fraction: float = 0.4, min_files: int = 3):
    """Pixels flagged as outliers in at least max(min_files, min_fraction * n) of n files.

    **Arguments:** `outlier_lists`: per file (rows, cols, values) from `stats.outliers`;
    `shape`: mosaic (H, W).

    **Returns:** dict with rows, cols, values (median over the files that flag it), `count`,
    `expected` (chance count if each file's flags were independent of position: pixels x
    P(Binomial(n, mean flag rate) >= threshold)), `p` (Poisson tail of the observed count,
    P(N >= count | expected)) and `score` (the normal quantile of 1 - p, capped at 40).
    """
    height, width = shape
    n = len(outlier_lists)
    threshold = max(min_files, int(math.ceil(min_fraction * n)))
    flagged = [np.asarray(rows, np.int64) * width + np.asarray(cols, np.int64) for rows, cols, _ in outlier_lists]
    flagged = np.concatenate(flagged) if flagged else np.zeros(0, np.int64)
    flagged = flagged[(flagged >= 0) & (flagged < height * width)]
    pixels, hits = np.unique(flagged, return_counts=True)   # sparse: a few flags among millions of pixels
    chosen = pixels[hits >= threshold]
    values = []
    for index in chosen:
        per_file = [v[(r * width + c) == index] for r, c, v in outlier_lists]
        values.append(float(np.median(np.concatenate(per_file))))
    rate = np.mean([len(r) for r, _, _ in outlier_lists]) / (height * width) if n else 0.0
    expected = height * width * _scipy_stats.binom.sf(threshold - 1, n, rate) if n else 0.0
    count = len(chosen)
    p = float(_scipy_stats.poisson.sf(count - 1, max(expected, 1e-300))) if count else 1.0
    score = float(min(_scipy_stats.norm.isf(max(p, 1e-300)), 40.0)) if count else 0.0
    return {"rows": chosen // width, "cols": chosen % width, "values": np.asarray(values),
            "count": count, "expected": float(expected), "p": p, "score": max(score, 0.0)}


def likelihood_bootstrap(points, log_density, sample, *, n_boot: int = 2000, seed: int = 0) -> dict:
    """Monte Carlo goodness-of-fit: is the mean log density of `points` under a model lower than
    for samples of the same size drawn from the model itself? (parametric bootstrap test,
    Efron & Tibshirani, *An Introduction to the Bootstrap*, 1993, ch. 16).

    **Arguments:** `points` (n, d); `log_density(x)`: (m, d) -> (m,); `sample(m, seed)`: (m, d)
    draws from the model.

    **Returns:** dict with `observed` mean log density, `p` (one-sided, low) and `score`
    ((mean null - observed) / sd null).
    """
    points = np.asarray(points, np.float64)
    n = len(points)
    observed = float(np.mean(log_density(points)))
    draws = np.asarray(sample(n * n_boot, seed), np.float64)
    null = log_density(draws).reshape(n_boot, n).mean(axis=1)
    p = (1 + np.sum(null <= observed)) / (1 + n_boot)
    score = (null.mean() - observed) / max(null.std(), 1e-12)
    return {"observed": observed, "p": float(p), "score": float(score)}
