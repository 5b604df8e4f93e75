"""Robust spread estimates shared by the audit's statistics and its black-level evidence."""

from __future__ import annotations

import numpy as np

MAD_TO_STD = 1.482602            # 1 / Phi^-1(3/4): MAD of a Gaussian -> its standard deviation
KEEP = 0.9                       # share of the smallest squares kept
CHI2_1_TRIMMED_MEAN = 0.6230155  # mean of the smallest 90 % of chi-square(1) draws: rescales to the variance


def trimmed_variance(d):
    """Variance of zero-mean Gaussian samples from their trimmed second moment: the mean of the
    smallest `KEEP` of the squares over that of a chi-square(1) variable, so that a few outliers
    (edges, defects) do not raise it. The mean of the smallest 90 % of d^2 is 0.62302 sigma^2 for a
    zero-mean Gaussian d (chi-square(1) truncated at its 0.9 quantile 2.7055); unlike the median it
    is not stuck on the discrete values of integer DN."""
    if d.size == 0:
        return np.nan
    squares = d * d
    keep = max(1, int(KEEP * squares.size))
    return np.partition(squares, keep - 1)[:keep].mean() / CHI2_1_TRIMMED_MEAN


def mad_sd(values) -> float:
    """Standard deviation of Gaussian samples from their median absolute deviation (NaN when empty)."""
    values = np.asarray(values, np.float64).ravel()
    return float(MAD_TO_STD * np.median(np.abs(values - np.median(values)))) if values.size else np.nan
