"""`noise_model`: the noise variance differs from the profile's shot(ISO) x + read(ISO).

Measures log(measured / predicted variance) of the noise level function (`stats.noise_level_function`)
over dark (< 5 % of the range) and bright bins, per CFA position; extension: scale factors of
`NoiseModel.shot` and `NoiseModel.read` per position.
"""

from __future__ import annotations

import warnings

import numpy as np

from ... import profile as _profile
from .base import Cause, as_profile_dtype

DARK_LEVEL = 0.05   # NLF bins below this are read-noise dominated


def noise_prediction(profile, iso: float, level):
    """The profile's noise variance shot(iso) x + read(iso) per position, at `level` (4, B)."""
    isos = np.asarray(profile.noise.iso, np.float64)
    shot = np.array([np.interp(iso, isos, np.asarray(profile.noise.shot, np.float64)[:, p]) for p in range(4)])
    read = np.array([np.interp(iso, isos, np.asarray(profile.noise.read, np.float64)[:, p]) for p in range(4)])
    return shot[:, None] * np.maximum(level, 0) + read[:, None], shot, read


def noise_vector(s, profile) -> np.ndarray:
    """(8,) mean log(measured / predicted variance) over dark and over bright bins, per position."""
    predicted, _, _ = noise_prediction(profile, s["iso"], s["nlf_level"])
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.log(s["nlf_var"] / predicted)
    ratio[~np.isfinite(ratio)] = np.nan
    dark = s["nlf_level"] < DARK_LEVEL
    out = []
    for mask in (dark, ~dark):
        values = np.where(mask & np.isfinite(ratio), ratio, np.nan)
        counts = np.sum(np.isfinite(values), axis=1)
        out.append(np.where(counts > 0, np.nansum(values, axis=1) / np.maximum(counts, 1), np.nan))
    return np.concatenate(out)


def noise_scales(measured, simulated, profile):
    """Scale factors (shot (4,), read (4,)) by weighted least squares of
    var_measured / bias = s shot(iso) x + r read(iso), where bias is the simulated files' median
    ratio of estimated to true variance per bin (the estimator's own bias on these scenes)."""
    def ratios(files):
        return np.stack([f["nlf_var"] / noise_prediction(profile, f["iso"], f["nlf_level"])[0] for f in files])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        bias = np.nanmedian(ratios(simulated), axis=0)
    shot_scale, read_scale = np.ones(4), np.ones(4)
    for p in range(4):
        rows, target = [], []
        for f in measured:
            _, shot, read = noise_prediction(profile, f["iso"], f["nlf_level"])
            for b in range(f["nlf_var"].shape[1]):
                var, level = f["nlf_var"][p, b], f["nlf_level"][p, b]
                if not (np.isfinite(var) and np.isfinite(bias[p, b]) and bias[p, b] > 0):
                    continue
                predicted = shot[p] * max(level, 0) + read[p]
                rows.append(np.array([shot[p] * max(level, 0), read[p]]) / predicted)   # relative weights
                target.append(var / bias[p, b] / predicted)
        if len(rows) >= 3:
            solution = np.linalg.lstsq(np.asarray(rows), np.asarray(target), rcond=None)[0]
            shot_scale[p], read_scale[p] = np.clip(solution, 0.05, 20.0)
    return shot_scale, read_scale


class NoiseModel(Cause):
    name = "noise_model"
    statistic = ("log ratio of the measured noise level function to the profile's at the file's ISO, dark "
                 "(<5%) and bright bins, per CFA position")
    metric = "rms difference of log noise variance ratio"
    floor, tolerance = 0.01, 0.08

    def vectors(self, files, profile):
        return np.stack([noise_vector(f, profile) for f in files])

    def fit(self, measured, simulated, profile, *, seed=0):
        shot, read = noise_scales(measured, simulated, profile)
        return {"shot_scale": shot.tolist(), "read_scale": read.tolist()}

    def apply(self, profile, params):
        shot = profile.noise.shot * as_profile_dtype(profile, params["shot_scale"])[None]
        read = profile.noise.read * as_profile_dtype(profile, params["read_scale"])[None]
        return _profile.replace(profile, noise=_profile.replace(profile.noise, shot=shot, read=read))


CAUSE = NoiseModel()
