"""`noise_model`: the noise variance differs from the profile's noise model.

What it measures: the noise level function (NLF) of every measured file, per CFA position and
signal bin, from flat blocks of each checkerboard half of the file's tiles
(`evidence.nlf_halves`), with 95 % bootstrap intervals.

How it is tested: against the profile's closed form, not against re-simulated scenes: the model
predicts the variance shot(ISO) x + read(ISO) + 1/12 DN^2 (rounding) at every signal level x.
Per bin, L = log(measured / predicted), its standard error from the interval, the two halves
combined by inverse variance, minus the estimator's own bias where the simulated files show one
(their median L per bin, usually ~0). z = L / se; score = max |z| over bins, positions and files;
p Bonferroni over those bins. Significant when p is below the threshold and some bin deviates by
more than `tolerance` in log variance beyond two standard errors. One file is enough: its
thousands of blocks give the intervals.

Extension: scale factors of `NoiseModel.shot` and `NoiseModel.read` per position, fitted by
weighted least squares on the bins of half A of the fit files. Held-out: the RMS of L on half B
of held-out files (or of the one file) before and after.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import stats as _scipy_stats

from ... import profile as _profile
from .base import Cause, as_profile_dtype

DARK_LEVEL = 0.05   # NLF bins below this are read-noise dominated
MIN_BLOCKS = 30
_Z95 = 1.959964


def noise_prediction(profile, iso: float, level):
    """The profile's noise variance shot(iso) x + read(iso) per position, at `level` (4, B)."""
    isos = np.asarray(profile.noise.iso, np.float64)
    shot = np.array([np.interp(iso, isos, np.asarray(profile.noise.shot, np.float64)[:, p]) for p in range(4)])
    read = np.array([np.interp(iso, isos, np.asarray(profile.noise.read, np.float64)[:, p]) for p in range(4)])
    return shot[:, None] * np.maximum(level, 0) + read[:, None], shot, read


def model_variance(profile, f, signal) -> np.ndarray:
    """Variance the profile predicts for file `f` at `signal` (4, B): noise model + rounding."""
    return noise_prediction(profile, f["iso"], signal)[0] + f["quantisation"][:, None]


def log_ratio(profile, f, half: str):
    """(L, se, signal) of one half of a file: log(measured / predicted variance) per (position,
    bin), its standard error from the 95 % interval, and the bins' signal; NaN where unusable."""
    e = f["nlf"][half]
    with np.errstate(invalid="ignore", divide="ignore"):
        usable = (np.asarray(e.counts) >= MIN_BLOCKS) & (e.variance > 0) & (e.lower > 0) & (e.signal > 0)
        L = np.where(usable, np.log(e.variance) - np.log(model_variance(profile, f, e.signal)), np.nan)
        se = np.where(usable, (np.log(e.upper) - np.log(e.lower)) / (2 * _Z95), np.nan)
    return L, np.maximum(se, 1e-3), np.where(usable, e.signal, np.nan)


def combined(profile, f):
    """Both halves of a file, combined by inverse variance: (L, se, signal) per (position, bin)."""
    parts = [log_ratio(profile, f, h) for h in ("A", "B")]
    weights = [np.where(np.isfinite(L), 1 / se**2, 0.0) for L, se, _ in parts]
    total = weights[0] + weights[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        L = sum(w * np.nan_to_num(p[0]) for w, p in zip(weights, parts)) / total
        signal = sum(w * np.nan_to_num(p[2]) for w, p in zip(weights, parts)) / total
        se = 1 / np.sqrt(total)
    return np.where(total > 0, L, np.nan), np.where(total > 0, se, np.nan), np.where(total > 0, signal, np.nan)


def estimator_bias(profile, simulated) -> np.ndarray:
    """(4, B) median L over the simulated files (which follow the model exactly): what the
    estimator itself adds on these scenes; 0 where fewer than 3 files have the bin."""
    if not simulated:
        return 0.0
    values = np.stack([combined(profile, f)[0] for f in simulated])
    counts = np.sum(np.isfinite(values), 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        bias = np.nanmedian(values, 0)
    return np.where(counts >= 3, bias, 0.0)


def noise_vector(f, profile) -> np.ndarray:
    """(8,) mean L over dark (< 5 %) and over bright bins, per position (a per-file summary)."""
    L, _, signal = combined(profile, f)
    out = []
    for mask in (signal < DARK_LEVEL, signal >= DARK_LEVEL):
        values = np.where(mask & np.isfinite(L), L, np.nan)
        counts = np.sum(np.isfinite(values), axis=1)
        out.append(np.where(counts > 0, np.nansum(values, axis=1) / np.maximum(counts, 1), np.nan))
    return np.concatenate(out)


def fit_scales(files, profile, half: str = "A", bias=0.0):
    """Scale factors (shot (4,), read (4,)) so that s shot x + r read + q matches the measured
    variance of `half` of the files' tiles, by least squares on relative residuals weighted by
    the bins' log standard errors."""
    shot_scale, read_scale = np.ones(4), np.ones(4)
    for p in range(4):
        rows, target, weights = [], [], []
        for f in files:
            e = f["nlf"][half]
            L, se, signal = log_ratio(profile, f, half)
            _, shot, read = noise_prediction(profile, f["iso"], signal)
            b = np.broadcast_to(bias, L.shape)
            for k in np.flatnonzero(np.isfinite(L[p])):
                predicted = shot[p] * signal[p, k] + read[p] + f["quantisation"][p]
                measured = e.variance[p, k] * np.exp(-b[p, k]) - f["quantisation"][p]
                rows.append(np.array([shot[p] * signal[p, k], read[p]]) / predicted)
                target.append(measured / predicted)
                weights.append(1 / se[p, k])
        if len(rows) >= 2:
            w = np.asarray(weights)
            solution = np.linalg.lstsq(np.asarray(rows) * w[:, None], np.asarray(target) * w, rcond=None)[0]
            shot_scale[p], read_scale[p] = np.clip(solution, 0.02, 50.0)
    return shot_scale, read_scale


class NoiseModel(Cause):
    name = "noise_model"
    statistic = ("noise level function per CFA position (variance of flat 8x8 blocks, per signal bin, "
                 "95 % bootstrap intervals) against the profile's closed-form variance shot x + read + 1/12 DN^2")
    metric = "rms of log(measured / model variance) over the bins of held-out regions"
    floor, tolerance = 0.01, 0.1
    region_heldout = True

    def vectors(self, files, profile):
        return np.stack([noise_vector(f, profile) for f in files])

    def test(self, measured, simulated, profile, *, n_permutations=2000, seed=0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return self._test(measured, simulated, profile)

    def _test(self, measured, simulated, profile):
        bias = estimator_bias(profile, simulated)
        zs, Ls, ses, signals = [], [], [], []
        for f in measured:
            L, se, signal = combined(profile, f)
            L = L - bias
            zs.append(L / se)
            Ls.append(L)
            ses.append(se)
            signals.append(signal)
        z, L, se, signal = (np.stack(v) for v in (zs, Ls, ses, signals))
        finite = np.isfinite(z)
        if not finite.any():
            return {"cause": self.name, "score": 0.0, "p": 1.0, "magnitude": 0.0, "statistic": self.statistic,
                    "evidence": "no flat regions to measure the noise in", "difference": []}
        score = float(np.nanmax(np.abs(z)))
        p = float(min(1.0, finite.sum() * 2 * _scipy_stats.norm.sf(score)))
        beyond = np.where(finite, np.maximum(np.abs(L) - 2 * se, 0.0), 0.0)
        magnitude = float(beyond.max())
        worst = np.unravel_index(np.nanargmax(np.where(finite, np.abs(z), -1)), z.shape)
        ratio = np.exp(L)
        levels = np.nanmedian(signal, axis=(0, 1))
        per_level = np.nanmedian(ratio, axis=(0, 1))
        table = ", ".join(f"{100 * x:.2g}%: x{r:.2f}" for x, r in zip(levels, per_level) if np.isfinite(r))
        evidence = (f"measured / model noise variance by signal level (median over positions and files): {table}; "
                    f"largest deviation x{ratio[worst]:.3g} at {100 * signal[worst]:.3g}% of range, CFA position "
                    f"{worst[1]}, z = {z[worst]:.1f}; {int(finite.sum())} bins, Bonferroni p = {p:.3g}")
        return {"cause": self.name, "score": score, "p": p, "magnitude": magnitude, "statistic": self.statistic,
                "evidence": evidence, "difference": np.nan_to_num(np.nanmedian(L, axis=0)).tolist() if len(L) else [],
                "plot": _plot_data(profile, measured)}

    def fit(self, measured, simulated, profile, *, seed=0):
        bias = estimator_bias(profile, simulated)
        shot, read = fit_scales(measured, profile, "A", bias)
        return {"shot_scale": shot.tolist(), "read_scale": read.tolist()}

    def apply(self, profile, params):
        shot = profile.noise.shot * as_profile_dtype(profile, params["shot_scale"])[None]
        read = profile.noise.read * as_profile_dtype(profile, params["read_scale"])[None]
        return _profile.replace(profile, noise=_profile.replace(profile.noise, shot=shot, read=read))

    def discrepancy(self, measured, simulated, profile, *, seed=0, half="B"):
        bias = estimator_bias(profile, simulated) if simulated is not None else 0.0
        values = np.concatenate([(log_ratio(profile, f, half)[0] - bias).ravel() for f in measured])
        values = values[np.isfinite(values)]
        return float(np.sqrt(np.mean(values**2))) if values.size else 0.0

    def heldout(self, fit_files, held_files, simulated, profile, simulate_stats, *, seed=0):
        """Fit on half A of the fit files' tiles, compare on half B of the held-out files (regions
        and files the fit did not see); closed form, no re-simulation."""
        extended = self.apply(profile, self.fit(fit_files, simulated, profile, seed=seed))
        bias = estimator_bias(profile, simulated)
        def rms(p):
            values = np.concatenate([(log_ratio(p, f, "B")[0] - bias).ravel() for f in held_files])
            values = values[np.isfinite(values)]
            return float(np.sqrt(np.mean(values**2))) if values.size else 0.0
        return rms(profile), rms(extended)


def _plot_data(profile, files) -> dict:
    """Per file and position: signal, measured variance and interval, model variance (DN^2 is
    left to the report: here normalised units)."""
    out = []
    for f in files[:4]:
        e = f["nlf"]["A"]
        rows = {}
        for half in ("A", "B"):
            e = f["nlf"][half]
            rows[half] = {"signal": np.asarray(e.signal).tolist(), "variance": np.asarray(e.variance).tolist(),
                          "lower": np.asarray(e.lower).tolist(), "upper": np.asarray(e.upper).tolist(),
                          "model": model_variance(profile, f, np.asarray(e.signal)).tolist()}
        out.append({"name": f.get("name", ""), "iso": f["iso"], "span": f.get("span"), "halves": rows})
    return {"kind": "nlf", "files": out}


CAUSE = NoiseModel()
