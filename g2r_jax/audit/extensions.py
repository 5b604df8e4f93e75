"""Model extensions: for each cause, fit its parameters from measured files (against files
simulated by the current profile) and apply them to the profile as a new component.

`fit(cause, measured, simulated, profile)` -> params (JSON-ready dict);
`apply(profile, cause, params)` -> the extended profile. The simulated files carry the
profile's current parameters, so every fit is "current value + measured - simulated" in the
statistic's own scale, which cancels the estimator's scene-dependent bias to first order.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .. import illuminants as _illuminants
from .. import profile as _profile
from . import measures, significance

SHRINKAGE = 3.0   # pseudo-points pulling mixture covariances towards the pooled covariance


def _mean(cause, files, profile):
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(measures.vectors(cause, files, profile), axis=0)


def _delta(cause, measured, simulated, profile):
    return np.nan_to_num(_mean(cause, measured, profile) - _mean(cause, simulated, profile))


def _span(profile):
    return float(profile.white_level) - np.asarray(profile.black_level, np.float64)


def _noise_scales(measured, simulated, profile):
    """Scale factors (shot (4,), read (4,)) by weighted least squares of
    var_measured / bias = s shot(iso) x + r read(iso), where bias is the simulated files' median
    ratio of estimated to true variance per bin (the estimator's own bias on these scenes)."""
    def ratios(files):
        return np.stack([f["nlf_var"] / measures.noise_prediction(profile, f["iso"], f["nlf_level"])[0] for f in files])
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        bias = np.nanmedian(ratios(simulated), axis=0)
    shot_scale, read_scale = np.ones(4), np.ones(4)
    for p in range(4):
        rows, target = [], []
        for f in measured:
            _, shot, read = measures.noise_prediction(profile, f["iso"], f["nlf_level"])
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


def _per_colour(profile, values):
    """Average over the CFA positions of one colour (the two greens of a Bayer tile); used for
    the shading fall-off and the added black pedestal.

    Lens and colour shading is a property of the optics and the colour filter, so both green
    positions share one fall-off. Fitting them apart lets the noise of two estimates become a
    radial Gr/Gb gain difference in the extended profile, which the next round then "finds" as
    green imbalance; a Gr/Gb gain mismatch is `green_imbalance`'s parameter, not shading's.
    """
    cfa = np.asarray(profile.cfa_pattern)
    values = np.asarray(values, np.float64)
    return np.array([values[cfa == cfa[p]].mean() for p in range(len(values))])


def _shading_fit(profile, delta_log_corner):
    """Per position (a1, a2) so that 1 + a1 t + a2 t^2 ~ old gain(t) * exp(delta * t), t = r^2."""
    t = np.linspace(0, 1, 21)
    old = np.asarray(profile.effects.shading, np.float64)
    design = np.stack([t, t**2], 1)
    out = np.zeros((4, 2))
    for p in range(4):
        target = (1 + old[p, 0] * t + old[p, 1] * t**2) * np.exp(delta_log_corner[p] * t) - 1
        out[p] = np.linalg.lstsq(design, target, rcond=None)[0]
    return out


def fit(cause: str, measured: list, simulated: list, profile, *, seed: int = 0) -> dict:
    """Fit the parameters of `cause`'s extension; see the module docstring."""
    effects = profile.effects
    if cause == "black_level":
        # one added pedestal per colour: two noisy per-green estimates would leave a Gr/Gb offset
        # difference in the extended profile that reads as green imbalance in the next round
        delta = _per_colour(profile, _delta(cause, measured, simulated, profile) * _span(profile))
        pedestal = np.asarray(effects.black_pedestal, np.float64) + delta
        return {"black_pedestal_dn": pedestal.tolist(),
                "offset_fraction": float(np.mean(pedestal / _span(profile)))}
    if cause == "white_level":
        level = float(effects.clip_level) + float(np.median(_delta(cause, measured, simulated, profile)))
        return {"clip_level": float(min(level, 1.0))}
    if cause == "green_imbalance":
        greens = np.flatnonzero(np.asarray(profile.cfa_pattern) == 1)[:2]
        gain = np.asarray(effects.channel_gain, np.float64)
        ratio = float(np.exp(_delta(cause, measured, simulated, profile)[0]) * gain[greens[1]] / gain[greens[0]])
        return {"green2_over_green1": ratio, "positions": [int(g) for g in greens]}
    if cause == "lens_shading":
        shading = _shading_fit(profile, _per_colour(profile, _delta(cause, measured, simulated, profile)))
        return {"shading": shading.tolist(), "corner_gain": (1 + shading.sum(1)).tolist()}
    if cause == "noise_model":
        shot, read = _noise_scales(measured, simulated, profile)
        return {"shot_scale": shot.tolist(), "read_scale": read.tolist()}
    if cause == "banding":
        delta = _delta(cause, measured, simulated, profile)
        old = np.array([float(effects.row_noise_std), float(effects.column_noise_std)])
        std = np.sqrt(np.maximum(old**2 + delta, 0.0))
        return {"row_noise_std": float(std[0]), "column_noise_std": float(std[1])}
    if cause == "exposure_distribution":
        m = measures.vectors(cause, measured, profile)[:, 0]
        s = measures.vectors(cause, simulated, profile)[:, 0]
        old_std = float(profile.exposure.log2_std)
        std = np.sqrt(max(old_std**2 + np.nanvar(m, ddof=1) - np.nanvar(s, ddof=1), 0.0))
        return {"log2_mean": float(profile.exposure.log2_mean) + float(np.nanmean(m) - np.nanmean(s)),
                "log2_std": float(std)}
    if cause == "defective_pixels":
        found = significance.consistent_outliers([f["outliers"] for f in measured], measured[0]["shape"])
        existing = {(int(r), int(c)) for r, c in zip(np.asarray(effects.defect_rows), np.asarray(effects.defect_cols))}
        new = [[int(r), int(c), float(np.clip(v, 0, 1))] for r, c, v in zip(found["rows"], found["cols"], found["values"])
               if (int(r), int(c)) not in existing]
        return {"count": len(new), "defects": new}
    if cause == "illuminant_distribution":
        points = measures.neutral_chromaticities(measured)
        model = _illuminants.fit_mixture(points, seed=seed)
        chol = np.asarray(model.cholesky, np.float64)
        weights = np.asarray(model.weights, np.float64)
        # Shrink each component's covariance towards the pooled one with SHRINKAGE pseudo-points
        # (a conjugate inverse-Wishart prior, e.g. Fraley & Raftery, "Bayesian regularization for
        # normal mixture estimation", J. Classification 2007): a few files per lamp type must not
        # give a needle-thin component.
        covariances = chol @ np.swapaxes(chol, -1, -2)
        counts = weights * len(points)
        pooled = np.cov(points.T)
        covariances = (counts[:, None, None] * covariances + SHRINKAGE * pooled) / (counts[:, None, None] + SHRINKAGE)
        return {"kind": model.kind, "weights": weights.tolist(), "means": np.asarray(model.means).tolist(),
                "covariances": covariances.tolist(), "hull_points": points.tolist()}
    raise ValueError(f"no extension for cause {cause!r}")


def _effects(profile, **changes):
    return _profile.replace(profile, effects=_profile.replace(profile.effects, **changes))


def apply(profile, cause: str, params: dict):
    """The profile extended by `cause`'s fitted parameters."""
    dtype = profile.effects.black_pedestal.dtype
    as_j = lambda v: jnp.asarray(v, dtype)
    if cause == "black_level":
        return _effects(profile, black_pedestal=as_j(params["black_pedestal_dn"]))
    if cause == "white_level":
        return _effects(profile, clip_level=as_j(params["clip_level"]))
    if cause == "green_imbalance":
        gain = np.asarray(profile.effects.channel_gain, np.float64).copy()
        g1, g2 = params["positions"]
        gain[g2] = gain[g1] * params["green2_over_green1"]
        return _effects(profile, channel_gain=as_j(gain))
    if cause == "lens_shading":
        return _effects(profile, shading=as_j(params["shading"]))
    if cause == "noise_model":
        shot = profile.noise.shot * as_j(params["shot_scale"])[None]
        read = profile.noise.read * as_j(params["read_scale"])[None]
        return _profile.replace(profile, noise=_profile.replace(profile.noise, shot=shot, read=read))
    if cause == "banding":
        return _effects(profile, row_noise_std=as_j(params["row_noise_std"]),
                        column_noise_std=as_j(params["column_noise_std"]))
    if cause == "exposure_distribution":
        exposure = _profile.replace(profile.exposure, log2_mean=as_j(params["log2_mean"]),
                                    log2_std=as_j(params["log2_std"]))
        return _profile.replace(profile, exposure=exposure)
    if cause == "defective_pixels":
        defects = np.asarray(params["defects"], np.float64).reshape(-1, 3)
        e = profile.effects
        return _effects(profile,
                        defect_rows=jnp.concatenate([e.defect_rows, jnp.asarray(defects[:, 0], jnp.int32)]),
                        defect_cols=jnp.concatenate([e.defect_cols, jnp.asarray(defects[:, 1], jnp.int32)]),
                        defect_values=jnp.concatenate([e.defect_values, as_j(defects[:, 2])]))
    if cause == "illuminant_distribution":
        points = np.asarray(params["hull_points"], np.float64)
        use_hull = bool(profile.illuminants.use_hull)
        hull = _illuminants.convex_hull_halfplanes(points) if use_hull else None
        model = _illuminants._model(params["weights"], params["means"], params["covariances"], hull,
                                    params["kind"], use_hull, dtype)
        return _profile.replace(profile, illuminants=model)
    raise ValueError(f"no extension for cause {cause!r}")
