"""Fit a noise model to what a file's own pixels show (`g2r_jax.sensor.noise.estimation`).

- `extended_noise_model(estimate, noise, black_level, white_level, correlation=...)`: the
  `NoiseModel` with a noise level function per CFA position (piecewise linear on `DEFAULT_KNOTS`,
  optionally monotone) and a 3 x 3 correlation kernel per position (`g2r_jax.sensor.noise.shape`);
  `g2r_jax.profile.editing.fit_noise_extension` puts it in a profile.
- `fit_correlation_by_level(estimate)`: a 3 x 3 kernel per position and its share by signal
  level (`NoiseModel.correlation_knots`, `correlation_weight`), for noise that is smoothed only
  at some levels (in-camera denoising above a signal level); `autocorrelation_at_levels(noise,
  signal)`: the autocorrelation a NoiseModel simulates there.
- `fit_shot_read(estimate)`: the DNG NoiseProfile model, variance = shot * x + read, per
  position (for files without a usable NoiseProfile tag).
- `predicted_variance(noise, iso, signal)`: what a NoiseModel (with or without the extension)
  predicts at measured signal levels, to compare with an estimate.

Fits are scipy least squares on a few dozen numbers (analysis, not the simulation core).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from scipy.optimize import least_squares

from g2r_jax.sensor.noise import estimation as _estimation

# Normalised signal knots of the level function: 0, then three per octave from 2^-10 to 1.
DEFAULT_KNOTS = np.concatenate([[0.0], np.geomspace(2.0**-10, 1.0, 31)])
SMOOTHNESS = 1.0   # weight of the second-difference penalty on log variance, in units of one bin's SE


def _log_se(estimate, p, b):
    """Standard error of log variance of one bin, from its bootstrap interval."""
    from scipy.stats import norm

    z = norm.ppf(1 - (1 - estimate.confidence) / 2)
    return max((np.log(estimate.upper[p, b]) - np.log(estimate.lower[p, b])) / (2 * z), 1e-3)


def _bins(estimate, p, floor_variance: float = 0.0):
    ok = np.flatnonzero(estimate.valid()[p] & (estimate.lower[p] > 0))
    signal = estimate.signal[p, ok]
    variance = estimate.variance[p, ok]
    variance = np.maximum(variance - floor_variance, 0.1 * variance)
    se = np.array([_log_se(estimate, p, b) for b in ok])
    return signal, variance, se


def fit_level_function(estimate, *, knots=DEFAULT_KNOTS, monotone: bool = False, floor_variance=None,
                       smoothness: float = SMOOTHNESS) -> np.ndarray:
    """(4, K) variances at `knots` fitted to a `NoiseLevelEstimate`.

    Weighted least squares in log variance (weights from each bin's interval), the level
    function being linear in x between knots; a second-difference penalty on log variance
    (`smoothness`, per knot) carries the curve through knots without data between measured bins;
    beyond the measured range it is held at its value at the first and last bin. With `monotone`, the
    log variances are a + cumsum(softplus(d)), so the function never decreases with the signal
    (a physical sensor's noise grows with the signal; Foi et al. 2008, Sec. II). Not the default:
    lossy raw compression makes the measured function fall in places (the GoPro HERO6 frame's
    green variance drops from 1.8e-5 at x = 0.10 to 7.7e-6 at x = 0.27, intervals +-2 %), and on
    its held-out regions the free fit's mean |log ratio| is 0.09 against 0.25 for the monotone
    one (benchmarks/noise_gopro.py). Solved by Levenberg-Marquardt (scipy). `floor_variance`
    (4,) is subtracted from the measured variances first (e.g. `quantisation_variance`: the simulation adds rounding itself).
    """
    knots = np.asarray(knots, np.float64)
    floor_variance = np.zeros(4) if floor_variance is None else np.resize(np.asarray(floor_variance, np.float64), 4)
    out = np.full((4, len(knots)), np.nan)
    for p in range(4):
        signal, variance, se = _bins(estimate, p, floor_variance[p])
        if len(signal) < 2:
            continue
        start = np.interp(knots, signal, np.log(variance))

        def values(theta):
            if not monotone:
                return theta
            return theta[0] + np.concatenate([[0.0], np.cumsum(np.logaddexp(0.0, theta[1:]))])

        def residuals(theta):
            log_v = np.clip(values(theta), -80.0, 5.0)
            model = np.log(np.interp(signal, knots, np.exp(log_v)))
            return np.concatenate([(model - np.log(variance)) / se, smoothness * np.diff(log_v, 2)])

        if monotone:
            steps = np.maximum(np.diff(np.maximum.accumulate(start)), 1e-3)
            theta0 = np.concatenate([[start[0]], np.log(np.expm1(steps))])
        else:
            theta0 = start
        fitted = np.exp(np.clip(values(least_squares(residuals, theta0, method="lm", xtol=1e-10, ftol=1e-10).x),
                                -80.0, 5.0))
        out[p] = _held_beyond_data(knots, fitted, signal.min(), signal.max())
    return out


def _held_beyond_data(knots, variance, low, high) -> np.ndarray:
    """The fitted function held constant below the lowest and above the highest measured bin.
    The smoothness penalty alone would carry the last measured slope on in log x, a power law
    that goes to zero at black: on the GoPro frame the red variance at x = 0 came out at 4 DN^2
    against 170 DN^2 measured at x = 0.0034 (read noise does not vanish in the dark)."""
    at_low, at_high = np.interp([low, high], knots, variance)
    return np.where(knots < low, at_low, np.where(knots > high, at_high, variance))


def fit_correlation_kernel(correlation: _estimation.NoiseCorrelationEstimate) -> np.ndarray:
    """(4, 3, 3) kernels k (unit sum of squares) whose autocorrelation k * k matches the measured
    5 x 5 autocorrelation of each position (least squares, weights 1 / bootstrap SD; scipy's
    Levenberg-Marquardt from a near-identity kernel). Identity where nothing was measured."""
    kernels = np.zeros((4, 3, 3))
    kernels[:, 1, 1] = 1.0
    for p in range(4):
        if np.all(np.isfinite(correlation.rho[p])):
            kernels[p] = kernel_for_autocorrelation(correlation.rho[p], np.maximum(correlation.sd[p], 1e-3))
    return kernels


def kernel_for_autocorrelation(rho, sd=None) -> np.ndarray:
    """(3, 3) kernel k (unit sum of squares) whose autocorrelation matches `rho` (13,) at
    `sensor.noise.estimation.LAGS` (weights 1 / `sd`; Levenberg-Marquardt from a near-identity kernel)."""
    target = _estimation._window(rho)
    sd = _estimation._window(np.ones(len(rho)) if sd is None else sd)

    def residuals(flat):
        k = flat.reshape(3, 3)
        padded = np.pad(k, 2)
        auto = np.array([[np.sum(k * padded[2 + dy:5 + dy, 2 + dx:5 + dx]) for dx in range(-2, 3)]
                         for dy in range(-2, 3)])
        return np.delete(((auto / auto[2, 2] - target) / sd).reshape(-1), 12)   # lag 0 is 1 by construction

    start = np.array([[0.05, 0.1, 0.05], [0.1, 1.0, 0.1], [0.05, 0.1, 0.05]]).reshape(-1)
    k = least_squares(residuals, start, method="lm", xtol=1e-12, ftol=1e-12).x.reshape(3, 3)
    return k / np.sqrt(np.sum(k * k))


def blended_kernel(kernel, weight) -> np.ndarray:
    """(1 - w) delta + w k for a (3, 3) kernel k of unit sum of squares (`sensor.noise.shape`)."""
    out = np.asarray(weight, np.float64) * np.asarray(kernel, np.float64)
    out[1, 1] += 1.0 - weight
    return out


def autocorrelation_at_levels(noise, signal) -> np.ndarray:
    """(4, B, 13) autocorrelation of the noise a NoiseModel simulates at `signal` (4, B), at
    `sensor.noise.estimation.LAGS` (0 beyond lag 0 for white noise): its kernel, blended with delta by
    its weight at each level where it has one (`sensor.noise.shape`)."""
    signal = np.asarray(signal, np.float64)
    out = np.zeros(signal.shape + (len(_estimation.LAGS),))
    out[..., 0] = 1.0
    if noise.correlation_kernel is None:
        return out
    kernels = np.asarray(noise.correlation_kernel, np.float64)
    kernels = kernels / np.sqrt(np.sum(kernels**2, axis=(1, 2), keepdims=True))
    for p in range(signal.shape[0]):
        if noise.correlation_weight is None:
            weights = np.ones(signal.shape[1])
        else:
            weights = np.interp(signal[p], np.asarray(noise.correlation_knots, np.float64),
                                np.asarray(noise.correlation_weight, np.float64)[p])
        for b, w in enumerate(weights):
            out[p, b] = kernel_autocorrelation(blended_kernel(kernels[p], w)) if np.isfinite(w) else np.nan
    return out


WEIGHT_GRID = np.linspace(0.0, 1.0, 101)
CORRELATED = 0.05   # mean autocorrelation at the three nearest lags above which a bin counts as correlated
STRONGEST = 0.85    # bins within this share of the strongest correlation give the kernel (not those half blended)


def fit_correlation_by_level(estimate, *, knots=DEFAULT_KNOTS, min_blocks: int = 30):
    """(kernels (4, 3, 3), knots (K,), weight (4, K)): the noise's correlation as a function of the
    signal, from the lag statistics of each bin of a `NoiseLevelEstimate` (its `autocovariance`,
    measured with the variance: rho(l) = C(l) / C(0) per bin).

    Per position: the kernel (`kernel_for_autocorrelation`) from the block-weighted mean rho of
    the bins whose correlation at the lags (0, 1), (1, 0), (1, 1) is at least `STRONGEST` of the
    strongest bin's; then, per bin, the kernel's share w in [0, 1] whose blend (1 - w) delta + w k
    (`blended_kernel`) matches that bin's rho at the 12 lags best (least squares on a grid of
    0.01); w is piecewise linear between the bins' signals on `knots`, held beyond them. A camera
    that smooths its noise only above a signal level (in-camera denoising, lossy raw codecs) reads
    w = 0 below it and w near 1 above. Where no bin is correlated (strongest below
    `CORRELATED`), the identity kernel and w = 0."""
    knots = np.asarray(knots, np.float64)
    lags = _estimation.LAGS
    near = [lags.index((0, 1)), lags.index((1, 0)), lags.index((1, 1))]
    kernels = np.zeros((4, 3, 3))
    kernels[:, 1, 1] = 1.0
    weight = np.zeros((4, len(knots)))
    for p in range(4):
        c = np.asarray(estimate.autocovariance[p], np.float64)
        ok = (np.asarray(estimate.counts[p]) >= min_blocks) & np.isfinite(c[:, 0]) & (c[:, 0] > 0) \
            & np.isfinite(estimate.signal[p])
        if not ok.any():
            continue
        rho = c[ok] / c[ok, :1]
        counts = np.asarray(estimate.counts[p], np.float64)[ok]
        strength = rho[:, near].mean(axis=1)
        if strength.max() < CORRELATED:
            continue
        strong = strength >= STRONGEST * strength.max()
        kernels[p] = kernel_for_autocorrelation(np.average(rho[strong], axis=0, weights=counts[strong]))
        candidates = np.stack([kernel_autocorrelation(blended_kernel(kernels[p], w)) for w in WEIGHT_GRID])
        best = WEIGHT_GRID[np.argmin(((rho[:, None, 1:] - candidates[None, :, 1:]) ** 2).sum(-1), axis=1)]
        weight[p] = np.interp(knots, estimate.signal[p][ok], best)
    return kernels, knots, weight


def kernel_autocorrelation(kernel) -> np.ndarray:
    """(13,) autocorrelation of a 3 x 3 kernel at `sensor.noise.estimation.LAGS`."""
    k = np.asarray(kernel, np.float64)
    padded = np.pad(k, 2)
    return np.array([np.sum(k * padded[2 + dy:5 + dy, 2 + dx:5 + dx]) for dy, dx in _estimation.LAGS]) / np.sum(k * k)


def fit_shot_read(estimate, *, floor_variance=None) -> tuple[np.ndarray, np.ndarray]:
    """(shot (4,), read (4,)) of variance = shot * x + read fitted to an estimate per position:
    weighted least squares on the relative residual (weights 1 / (variance * log SE)), both
    terms kept non-negative (scipy's bounded linear least squares). NaN where no bins."""
    from scipy.optimize import lsq_linear

    floor_variance = np.zeros(4) if floor_variance is None else np.resize(np.asarray(floor_variance, np.float64), 4)
    shot, read = np.full(4, np.nan), np.full(4, np.nan)
    for p in range(4):
        signal, variance, se = _bins(estimate, p, floor_variance[p])
        if len(signal) < 2:
            continue
        scale = 1.0 / (variance * se)
        design = np.stack([np.maximum(signal, 0.0), np.ones_like(signal)], 1) * scale[:, None]
        column_scale = np.array([1.0 / max(np.max(design[:, 0]), 1e-300), 1.0 / np.max(design[:, 1])])
        result = lsq_linear(design * column_scale, variance * scale, bounds=(0, np.inf))
        shot[p], read[p] = result.x * column_scale
    return shot, read


def predicted_variance(noise, iso: float, signal) -> np.ndarray:
    """(4, B) noise variance a NoiseModel predicts at `signal` (4, B) and `iso` (numpy): its level
    function where it has one, otherwise shot * x + read (ISO rows interpolated as the simulator
    does). Add `quantisation_variance` to compare with a measured estimate."""
    signal = np.asarray(signal, np.float64)
    isos = np.asarray(noise.iso, np.float64)
    if noise.level_variance is not None:
        table = np.asarray(noise.level_variance, np.float64)
        at_iso = np.stack([[np.interp(iso, isos, table[:, p, k]) for k in range(table.shape[2])] for p in range(4)])
        knots = np.asarray(noise.level_knots, np.float64)
        return np.stack([np.interp(signal[p], knots, at_iso[p]) for p in range(4)])
    shot = np.array([np.interp(iso, isos, np.asarray(noise.shot, np.float64)[:, p]) for p in range(4)])
    read = np.array([np.interp(iso, isos, np.asarray(noise.read, np.float64)[:, p]) for p in range(4)])
    return shot[:, None] * np.maximum(signal, 0) + read[:, None]


def extended_noise_model(estimate, noise, black_level, white_level, *, correlation=None, iso: float | None = None,
                         knots=DEFAULT_KNOTS, monotone: bool = False):
    """`noise` (a `NoiseModel`) extended by a measured level function (and correlation kernel).

    **Arguments:** `estimate`: a `NoiseLevelEstimate` of one file (or of several files of one
    ISO pooled); `black_level` (4,), `white_level`: the files' levels (the rounding variance,
    `estimation.quantisation_variance`, floors the fit); `correlation`: a
    `NoiseCorrelationEstimate` (None: no kernel); `iso`: the files' ISO (default: the model's,
    when it has one ISO row); `knots`, `monotone`: see `fit_level_function`.

    **Returns:** a `NoiseModel` whose `level_variance` holds the fitted function at the row of
    `iso` (added to the table if new) and, at the other ISO rows, the same function scaled by
    the ratio of the model's shot * x + read at that row to that at `iso` (the measured shape
    carried to the other ISOs). Positions without an estimate keep shot * x + read.
    """
    isos = np.asarray(noise.iso, np.float64)
    if iso is None:
        if len(isos) != 1:
            raise ValueError("the noise model has several ISO rows: say at which ISO the estimate was measured (iso=...)")
        iso = float(isos[0])
    knots = np.asarray(knots, np.float64)
    floor = _estimation.quantisation_variance(black_level, float(white_level))
    fitted = fit_level_function(estimate, knots=knots, monotone=monotone, floor_variance=floor)
    linear_at_iso = predicted_variance(_no_shape(noise), iso, np.broadcast_to(knots, (4, len(knots))))
    fitted = np.where(np.isfinite(fitted), fitted, linear_at_iso)
    new_isos = np.array(sorted(set(isos.tolist()) | {float(iso)}))
    shot = np.stack([[np.interp(i, isos, np.asarray(noise.shot, np.float64)[:, p]) for p in range(4)] for i in new_isos])
    read = np.stack([[np.interp(i, isos, np.asarray(noise.read, np.float64)[:, p]) for p in range(4)] for i in new_isos])
    rows = []
    for row_iso in new_isos:
        linear = predicted_variance(_no_shape(noise), row_iso, np.broadcast_to(knots, (4, len(knots))))
        ratio = np.where(linear_at_iso > 0, linear / np.maximum(linear_at_iso, 1e-300), 1.0)
        rows.append(fitted * ratio)
    dtype = noise.shot.dtype
    shape = {"iso": jnp.asarray(new_isos, dtype), "shot": jnp.asarray(shot, dtype), "read": jnp.asarray(read, dtype),
             "level_knots": jnp.asarray(knots, dtype), "level_variance": jnp.asarray(np.stack(rows), dtype)}
    if correlation is not None:
        shape["correlation_kernel"] = jnp.asarray(fit_correlation_kernel(correlation), dtype)
        shape.update(correlation_knots=None, correlation_weight=None)   # one kernel at every level
    return type(noise)(iso_range=noise.iso_range, **{**_fields(noise), **shape})


def _fields(noise) -> dict:
    return {"iso": noise.iso, "shot": noise.shot, "read": noise.read, "level_knots": noise.level_knots,
            "level_variance": noise.level_variance, "correlation_kernel": noise.correlation_kernel,
            "correlation_knots": noise.correlation_knots, "correlation_weight": noise.correlation_weight,
            "read_excludes_quantisation": noise.read_excludes_quantisation}


def _no_shape(noise):
    return type(noise)(iso=noise.iso, shot=noise.shot, read=noise.read, iso_range=noise.iso_range)
