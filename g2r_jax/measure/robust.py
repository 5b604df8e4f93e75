"""Robust spreads: the standard deviation of Gaussian samples from order statistics, so that a few
outliers (edges, defects, hot pixels) do not raise it.

- MAD: sd = 1.482602 x median |x - median x| (1 / Phi^-1(3/4); Hampel 1974).
- IQR: sd = (Q3 - Q1) / 1.348980 (2 Phi^-1(3/4)).
- Trimmed second moment of zero-mean samples (see `trimmed_variance`).

`robust_sd` adds a floor, the resolution of the statistic: a spread of zero (one repeated value,
integer DN, a statistic that reads 0 on every file) must not turn a difference into thousands of
standard deviations.
"""

from __future__ import annotations

import numpy as np

MAD_TO_STD = 1.482602            # 1 / Phi^-1(3/4): MAD of a Gaussian -> its standard deviation
IQR_TO_STD = 1.0 / 1.348980      # 1 / (2 Phi^-1(3/4)): interquartile range of a Gaussian -> its sd
KEEP = 0.9                       # share of the smallest squares kept
CHI2_1_TRIMMED_MEAN = 0.6230155  # mean of the smallest 90 % of chi-square(1) draws: rescales to the variance


def trimmed_variance(d):
    """Variance of zero-mean Gaussian samples from their trimmed second moment: the mean of the
    smallest `KEEP` of the squares over that of a chi-square(1) variable, so that a few outliers
    (edges, defects) do not raise it. The mean of the smallest 90 % of d^2 is 0.62302 sigma^2 for a
    zero-mean Gaussian d (chi-square(1) truncated at its 0.9 quantile 2.7055); unlike the median it
    is not stuck on the discrete values of integer DN."""
    d = np.asarray(d)
    if d.size == 0:
        return np.nan
    squares = d * d
    keep = max(1, int(KEEP * squares.size))
    return np.partition(squares.ravel(), keep - 1)[:keep].mean() / CHI2_1_TRIMMED_MEAN


def mad_sd(values) -> float:
    """Standard deviation of Gaussian samples from their median absolute deviation (NaN when empty)."""
    values = np.asarray(values, np.float64).ravel()
    return float(MAD_TO_STD * np.median(np.abs(values - np.median(values)))) if values.size else np.nan


def iqr_sd(values) -> float:
    """Standard deviation of Gaussian samples from their interquartile range (NaN when empty; 0
    when the middle half is one value: callers that divide by it use `robust_sd`)."""
    values = np.asarray(values, np.float64).ravel()
    if not values.size:
        return np.nan
    q1, q3 = np.percentile(values, [25, 75])
    return float((q3 - q1) * IQR_TO_STD)


def robust_sd(values, *, resolution: float = 0.0) -> float:
    """MAD spread of the finite `values`, never below `resolution` (the smallest difference the
    statistic can show: a count's 1/N, a DN step, a measurement's own noise).

    **Arguments:** `values`: samples; `resolution`: the floor, >= 0.

    **Returns:** the spread, or NaN when fewer than two finite values are given or the spread and
    the floor are both zero (a distance in units of it would be meaningless: callers say so).
    """
    values = np.asarray(values, np.float64).ravel()
    values = values[np.isfinite(values)]
    if values.size < 2:
        return float("nan")
    spread = max(mad_sd(values), float(resolution))
    return spread if spread > 0 else float("nan")
