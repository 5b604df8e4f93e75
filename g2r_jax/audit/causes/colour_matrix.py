"""`colour_matrix`: the profile's colour model does not predict the raw RGB the camera records.

Evidence: measured colour charts (`g2r_jax.charts`, `g2r-diagnose --charts`), not DNG files.
For each chart image the chart's known colours go through the profile's colour model with that
image's measured neutral (`colour_fit.predict_patches`, the closed form of `unprocess` without
noise); the statistic is the per-image residual log chromaticity of the 18 chromatic patches,
log(r/g) and log(b/g) measured minus predicted (36 components, NaN for unusable patches).

Test: the residuals are paired (same image, same light), so a one-sample maxT test over images
with sign-flip permutations (Westfall & Young, *Resampling-based multiple testing*, 1993;
sign flips are the permutation null of a paired test, Good, *Permutation Tests*, 2000, ch. 3).

Extension: a ColorMatrix pair (Standard Light A / D65) refitted to the charts
(`colour_fit.refit_colour_matrices`); validated by the mean chromatic angular error on held-out
images (the chart file's own folds when it has a `fold` column, else `measure.folds_of`). Also
reported: CIEDE2000 of the measured patches as a DNG renderer shows them, before and after.
"""

from __future__ import annotations

import warnings

import numpy as np

from g2r_jax.colour import charts as _charts
from g2r_jax.colour import chart_fit as colour_fit
from g2r_jax.audit.causes.base import Cause

LOG_CHROMA_FLOOR = 0.005  # ~0.5 % in a colour ratio: below the repeatability of chart patch means


def _log_chromaticity(rgb):
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.stack([np.log(rgb[..., 0] / rgb[..., 1]), np.log(rgb[..., 2] / rgb[..., 1])], -1)


def sign_flip_max_t(differences, *, floor=0.0, n_permutations: int = 2000, seed: int = 0) -> dict:
    """One-sample maxT test that the mean of paired differences (n, k) is zero, by sign flips.

    **Returns:** `t` (k,), `difference` (k,) mean, `p` ((1 + #{null >= obs}) / (1 + B)), `score`."""
    d = np.asarray(differences, np.float64)
    n = np.sum(np.isfinite(d), 0)

    def t_of(x):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(x, -2)
            sd = np.nanstd(x, -2, ddof=1)
        return np.where(n >= 3, mean / (np.nan_to_num(sd) / np.sqrt(np.maximum(n, 1)) + floor), 0.0), mean

    t, mean = t_of(d)
    observed = float(np.max(np.abs(t))) if t.size else 0.0
    signs = np.random.default_rng(seed).choice([-1.0, 1.0], size=(n_permutations, d.shape[0], 1))
    null = np.max(np.abs(np.nan_to_num(t_of(signs * d[None])[0])), axis=-1)
    return {"t": t, "difference": mean, "p": float((1 + np.sum(null >= observed)) / (1 + n_permutations)),
            "score": observed}


class ColourMatrix(Cause):
    name = "colour_matrix"
    evidence = "charts"      # tested on measured charts (`diagnose(..., charts=...)`), not DNG files
    statistic = ("residual log chromaticity log(r/g), log(b/g) of the 18 chromatic ColorChecker patches, "
                 "measured minus predicted by the colour model at the image's measured neutral, per chart image")
    metric = "mean chromatic angular error on held-out chart images (degrees)"
    floor, tolerance = LOG_CHROMA_FLOOR, 0.02

    def vectors(self, charts, profile) -> np.ndarray:
        predicted = colour_fit.predict_patches_np(profile.colour, charts)
        residual = (_log_chromaticity(charts.patches) - _log_chromaticity(predicted))[:, _charts.CHROMATIC]
        return residual.reshape(len(charts), -1)

    def test(self, measured, simulated, profile, *, n_permutations: int = 2000, seed: int = 0) -> dict:
        result = sign_flip_max_t(self.vectors(measured, profile), floor=self.floor,
                                 n_permutations=n_permutations, seed=seed)
        errors = colour_fit.colour_model_errors(profile.colour, measured)
        summary = colour_fit.summarise(errors)
        worst = int(np.nanargmax(summary["patch_median"]))
        rendered = float(np.nanmean(colour_fit.rendered_delta_E(profile.colour, measured)))
        magnitude = float(np.nanmax(np.abs(result["difference"]))) if np.any(np.isfinite(result["difference"])) else 0.0
        evidence = (f"{len(measured)} chart images: chromatic angular error mean {summary['chromatic_mean']:.2f} / "
                    f"median {summary['chromatic_median']:.2f} / p95 {summary['chromatic_p95']:.2f} deg, neutral "
                    f"{summary['neutral_mean']:.2f} deg; worst patch {worst + 1} ({_charts.PATCH_NAMES[worst]}) "
                    f"median {summary['patch_median'][worst]:.1f} deg; rendered (DNG white balance) mean "
                    f"CIEDE2000 {rendered:.2f}; max |mean log-chroma residual| "
                    f"{magnitude:.4f}, max |t| = {result['score']:.2f}, sign-flip p = {result['p']:.4g}")
        return {"cause": self.name, "score": result["score"], "p": result["p"], "magnitude": magnitude,
                "statistic": self.statistic, "evidence": evidence,
                "difference": np.nan_to_num(result["difference"]).tolist(),
                "patch_median_deg": summary["patch_median"]}

    def chart_plot(self, finding: dict) -> dict:
        """Plot data for the report: per patch, the median angular error over images of the
        profile's colour model and, when the refit was cross-validated, of the refitted pair on
        held-out images (`cross_validate`'s per-patch medians)."""
        gain = finding.get("gain") or {}
        return {"kind": "patches", "labels": list(_charts.PATCH_NAMES),
                "before": list(finding.get("patch_median_deg") or gain.get("patch_median_before") or []),
                "after": gain.get("patch_median_after"),
                "unit": "raw RGB angular error (deg), median over images",
                "title": f"{self.name}: measured chart patches against the colour model's prediction"}

    def fit(self, measured, simulated, profile, *, seed: int = 0) -> dict:
        start = colour_fit.as_pair(profile.colour, profile.info.calibration_illuminants)
        model, codes = colour_fit.refit_colour_matrices(start, measured)
        delta_before = np.nanmean(colour_fit.rendered_delta_E(profile.colour, measured))
        delta_after = np.nanmean(colour_fit.rendered_delta_E(model, measured))
        return {"calibration_illuminants": list(codes),
                "color_matrices": np.asarray(model.color_matrix, np.float64).tolist(),
                "camera_calibrations": np.asarray(model.camera_calibration, np.float64).tolist(),
                "fitted_on_images": len(measured),
                "rendered_delta_E_2000_mean": {"before": float(delta_before), "after": float(delta_after)}}

    def apply(self, profile, params):
        from g2r_jax.colour.dng_model import DngColourModel

        dtype = profile.colour.color_matrix.dtype
        model = DngColourModel.from_tags(params["calibration_illuminants"], params["color_matrices"],
                                         params["camera_calibrations"], (), np.asarray(profile.colour.analog_balance),
                                         dtype=dtype)
        return colour_fit.with_colour(profile, model, params["calibration_illuminants"],
                                      note=f"Colour matrices refitted by g2r-diagnose to {params['fitted_on_images']} "
                                           f"measured chart images (colour_matrix).")

    def discrepancy(self, measured, simulated, profile, *, seed: int = 0) -> float:
        return colour_fit.summarise(colour_fit.colour_model_errors(profile.colour, measured))["chromatic_mean"]

    def cross_validate(self, measured, profile, *, folds: int = 3, seed: int = 0) -> dict:
        """Held-out gain over the chart file's folds (or `measure.folds_of`)."""
        from g2r_jax.measure import folds_of

        if measured.folds is not None:
            fold_index = np.asarray(measured.folds)
        else:
            fold_index = np.empty(len(measured), int)
            for k, held in enumerate(folds_of(len(measured), folds, seed)):
                fold_index[held] = k
        result = colour_fit.cross_validated_refit(profile, measured, fold_index)
        before, after = colour_fit.summarise(result["before"]), colour_fit.summarise(result["after"])
        return {"metric": self.metric, "before": before["chromatic_mean"], "after": after["chromatic_mean"],
                "heldout": True, "folds": int(len(np.unique(fold_index))),
                "fold_before": result["fold_before"], "fold_after": result["fold_after"],
                "after_median": after["chromatic_median"], "after_p95": after["chromatic_p95"],
                "after_neutral_mean": after["neutral_mean"],
                "patch_median_before": before["patch_median"], "patch_median_after": after["patch_median"]}


CAUSE = ColourMatrix()
