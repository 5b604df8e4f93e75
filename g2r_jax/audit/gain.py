"""Held-out gain of an extension: the discrepancy between measured files the extension was not
fitted on and files simulated by the profile before and after the extension (K-fold
cross-validation over measured files; Stone, "Cross-validatory choice and assessment of
statistical predictions", JRSS B 1974). Lower is better; an extension is kept only if the mean
held-out discrepancy goes down.
"""

from __future__ import annotations

import warnings

import jax
import numpy as np

from .. import illuminants as _illuminants
from . import extensions, measures, significance

METRICS = {
    "black_level": "rms difference of the dark floor (fraction of range)",
    "white_level": "rms difference of the clipping level (fraction of range)",
    "green_imbalance": "difference of median log(G2/G1)",
    "lens_shading": "rms difference of corner log gain",
    "noise_model": "rms difference of log noise variance ratio",
    "banding": "rms difference of row/column offset variance",
    "exposure_distribution": "distance of (mean, std) of log2 centre brightness",
    "defective_pixels": "Jaccard distance between defect sets found in measured and simulated files",
    "illuminant_distribution": "mean negative log density of held-out as-shot neutrals (r/g, b/g) under the model",
}


def discrepancy(cause: str, measured: list, simulated: list, reference_profile, *, seed: int = 0) -> float:
    """How far the simulated files are from the measured ones in `cause`'s statistic."""
    if cause == "defective_pixels":
        a = significance.consistent_outliers([f["outliers"] for f in measured], measured[0]["shape"])
        b = significance.consistent_outliers([f["outliers"] for f in simulated], simulated[0]["shape"])
        sa, sb = set(zip(a["rows"].tolist(), a["cols"].tolist())), set(zip(b["rows"].tolist(), b["cols"].tolist()))
        return 0.0 if not (sa | sb) else 1.0 - len(sa & sb) / len(sa | sb)
    if cause == "illuminant_distribution":
        raise ValueError("use illuminant_discrepancy")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        m = measures.vectors(cause, measured, reference_profile)
        s = measures.vectors(cause, simulated, reference_profile)
        difference = np.nan_to_num(np.nanmean(m, 0) - np.nanmean(s, 0))
        if cause == "exposure_distribution":
            difference = np.append(difference, np.nan_to_num(np.nanstd(m, 0, ddof=1) - np.nanstd(s, 0, ddof=1)))
    return float(np.sqrt(np.mean(difference**2)))


def illuminant_samples(model, n: int, seed: int) -> np.ndarray:
    """(n, 2) chromaticities drawn from an illuminant model."""
    neutrals = np.asarray(_illuminants.sample_neutrals(jax.random.PRNGKey(seed), model, n), np.float64)
    return _illuminants.neutral_to_chromaticity(neutrals)


def folds_of(n: int, k: int, seed: int) -> list[np.ndarray]:
    """k disjoint held-out index sets covering range(n), shuffled by `seed`."""
    order = np.random.default_rng(seed).permutation(n)
    return [np.sort(order[i::k]) for i in range(k)]


def cross_validate(cause: str, measured: list, simulated: list, profile, simulate_stats, *,
                   folds: int = 3, seed: int = 0) -> dict:
    """K-fold held-out gain of `cause`'s extension.

    **Arguments:** `measured`, `simulated`: per-file statistics (the latter from `profile`);
    `simulate_stats(profile, cause)`: per-file statistics of files simulated by another profile (same
    scenes and random draws as `simulated`, so before/after differ only by the extension).

    **Returns:** {"metric", "before", "after", "heldout": True, "folds"}.
    """
    before, after = [], []
    for held in folds_of(len(measured), folds, seed):
        fit_files = [f for i, f in enumerate(measured) if i not in set(held.tolist())]
        held_files = [measured[i] for i in held]
        params = extensions.fit(cause, fit_files, simulated, profile, seed=seed)
        extended = extensions.apply(profile, cause, params)
        if cause == "illuminant_distribution":
            points = measures.neutral_chromaticities(held_files)
            before.append(-np.mean(_illuminants.mixture_log_likelihood(profile.illuminants, points)))
            after.append(-np.mean(_illuminants.mixture_log_likelihood(extended.illuminants, points)))
            continue
        resimulated = simulate_stats(extended, cause)
        before.append(discrepancy(cause, held_files, simulated, profile, seed=seed))
        after.append(discrepancy(cause, held_files, resimulated, profile, seed=seed))
    return {"metric": METRICS[cause], "before": float(np.mean(before)), "after": float(np.mean(after)),
            "heldout": True, "folds": folds}
