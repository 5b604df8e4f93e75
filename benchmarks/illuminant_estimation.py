"""The paper's experiment on real measurements: train an illuminant estimator on synthetic charts,
test it on real ones (Graphics2RAW, Seo et al. ICCV 2023, Tables 2 and S4, there on NUS images).

Test data: the real ColorChecker charts of one Gehler-Shi camera (chart CSV written by
`benchmarks/gehler_shi_charts.py`), the release's standard 3 folds: each fold is tested by an
estimator trained without it. Training data, one row each, same estimator for every row:

- (a) UPI: Brooks et al., "Unprocessing Images for Learned Raw Denoising", CVPR 2019: a random
  convex combination of their four XYZ->camera matrices (row-normalised after sRGB->XYZ), and
  white-balance gains red ~ U(1.9, 2.4), blue ~ U(1.5, 1.9) (illuminant = 1 / gains);
- (b) the published Graphics2RAW recipe (`unprocess(..., recipe="published")`) with the camera's
  Adobe D65 ColorMatrix;
- (c) g2r_jax as shipped (`unprocess`, exact DNG colour model) with the same matrix;
- (d) g2r_jax after the colour refit (`colour_fit.refit_colour_matrices` on the training folds);
- (e) Real: the training folds' real charts themselves.

(b)-(d) draw their illuminants from a Gaussian + hull fitted to the training folds' measured
illuminants (the published illuminant model); all synthetic rows use the chart's linear sRGB
(ColorChecker N Ohta under D65) with no noise, `TRAIN_PER_FOLD` charts per fold.

Estimator (the same for every row): the illuminant's log chromaticity (log r/g, log b/g) as the
average, over the usable chromatic patches (1-18; the neutral patches are not shown to it), of a
per-patch affine map of that patch's log chromaticity, fitted by least squares. Error: angle
between the estimated and the measured illuminant RGB (Hordley & Finlayson 2006); mean, median,
best 25 % (mean of the lowest quarter) and worst 25 % (mean of the highest quarter).

    python benchmarks/illuminant_estimation.py --charts out/gehler_shi_5d.csv --profile out/gehler_shi_5d.json \
        [--figure out/illuminant_estimation_5d.png] [--train-per-fold 2000] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys
import warnings
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from g2r_jax.colour import charts as _charts  # noqa: E402
from g2r_jax.colour import conversions as _colour  # noqa: E402
from g2r_jax.colour import chart_fit as colour_fit  # noqa: E402
from g2r_jax.pipeline import simulate_patches  # noqa: E402
from g2r_jax.downstream.base.upi import XYZ_TO_CAMERAS  # noqa: E402
from g2r_jax.measure import angular_error_degrees  # noqa: E402

TRAIN_PER_FOLD = 2000
ROWS = ("UPI (Brooks et al. 2019)", "published recipe", "g2r_jax as shipped", "g2r_jax after colour refit", "Real")


def log_chroma(rgb):
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.stack([np.log(rgb[..., 0] / rgb[..., 1]), np.log(rgb[..., 2] / rgb[..., 1])], -1)


class PatchwiseEstimator:
    """Per chromatic patch p: illuminant log-chroma ~ A_p [patch log-chroma, 1] (least squares);
    the estimate is the mean over the patches usable in that image."""

    def fit(self, patches, illuminant):
        features = log_chroma(patches[:, _charts.CHROMATIC])          # (N, 18, 2)
        target = log_chroma(illuminant)                              # (N, 2)
        self.maps = []
        for p in range(features.shape[1]):
            ok = np.all(np.isfinite(features[:, p]), -1)
            design = np.concatenate([features[ok, p], np.ones((ok.sum(), 1))], 1)
            self.maps.append(np.linalg.lstsq(design, target[ok], rcond=None)[0])
        return self

    def predict(self, patches):
        features = log_chroma(patches[:, _charts.CHROMATIC])
        design = np.concatenate([features, np.ones(features.shape[:2] + (1,))], -1)
        per_patch = np.einsum("npk,pkj->npj", design, np.stack(self.maps))
        with warnings.catch_warnings():   # an image without a usable chromatic patch: NaN, not scored
            warnings.simplefilter("ignore", RuntimeWarning)
            estimate = np.nanmean(per_patch, axis=1)
        return np.stack([np.exp(estimate[:, 0]), np.ones(len(estimate)), np.exp(estimate[:, 1])], -1)


def upi_charts(chart_linear, n, rng):
    """UPI training charts: (patches (n, 24, 3), illuminants (n, 3))."""
    weights = rng.uniform(1e-8, 1.0, (n, 4))
    weights /= weights.sum(1, keepdims=True)
    xyz_to_cam = np.einsum("nk,kij->nij", weights, XYZ_TO_CAMERAS)
    rgb_to_cam = xyz_to_cam @ np.asarray(_colour.MATRIX_SRGB_TO_XYZ)
    rgb_to_cam /= rgb_to_cam.sum(-1, keepdims=True)
    red, blue = rng.uniform(1.9, 2.4, n), rng.uniform(1.5, 1.9, n)
    illuminant = np.stack([1 / red, np.ones(n), 1 / blue], -1)
    camera = np.einsum("nij,pj->npi", rgb_to_cam, chart_linear) * illuminant[:, None]
    return camera, illuminant


def sampled_neutrals(illuminants, n, seed):
    import jax

    from g2r_jax.illuminants import distributions as il

    model = il.fit_gaussian(il.neutral_to_chromaticity(illuminants))
    return np.asarray(il.sample_neutrals(jax.random.PRNGKey(seed), model, n), np.float64)


def statistics(errors) -> dict:
    e = np.sort(errors[np.isfinite(errors)])
    q = max(1, len(e) // 4)
    return {"mean": e.mean(), "median": np.median(e), "best25": e[:q].mean(), "worst25": e[-q:].mean(),
            "n": len(e)}


def run(charts_path, profile_path, *, train_per_fold=TRAIN_PER_FOLD, seed=0, progress=print) -> dict:
    from g2r_jax.profile.schema import load_profile

    charts = _charts.read_charts(charts_path)
    profile = load_profile(profile_path)
    folds = _charts.folds_of(charts, 3, seed)
    chart_linear = _charts.chart_linear_srgb()
    chart_srgb = _charts.chart_srgb()
    rng = np.random.default_rng(seed)
    estimates = {row: np.full((len(charts), 3), np.nan) for row in ROWS}
    for fold in np.unique(folds):
        train, test = charts.subset(folds != fold), charts.subset(folds == fold)
        progress(f"fold {fold}: {len(train)} training, {len(test)} test images")
        neutrals = sampled_neutrals(train.illuminant, train_per_fold, seed + 1 + int(fold))
        start = colour_fit.as_pair(profile.colour, profile.info.calibration_illuminants)
        refit, codes = colour_fit.refit_colour_matrices(start, train)
        refit_profile = colour_fit.with_colour(profile, refit, codes)
        training = {
            ROWS[0]: upi_charts(chart_linear, train_per_fold, rng),
            ROWS[1]: (simulate_patches(profile, neutrals, chart_srgb, recipe="published"), neutrals),
            ROWS[2]: (simulate_patches(profile, neutrals, chart_srgb), neutrals),
            ROWS[3]: (simulate_patches(refit_profile, neutrals, chart_srgb), neutrals),
            ROWS[4]: (train.patches, train.illuminant),
        }
        for row, (patches, illuminant) in training.items():
            estimator = PatchwiseEstimator().fit(patches, illuminant)
            estimates[row][folds == fold] = estimator.predict(test.patches)
    errors = {row: angular_error_degrees(estimates[row], charts.illuminant, invalid="nan") for row in ROWS}
    return {"errors": errors, "statistics": {row: statistics(e) for row, e in errors.items()},
            "n_images": len(charts), "train_per_fold": train_per_fold}


def table(result) -> str:
    lines = ["| training data | mean | median | best 25 % | worst 25 % |", "|---|---|---|---|---|"]
    for row, s in result["statistics"].items():
        lines.append(f"| {row} | {s['mean']:.2f} | {s['median']:.2f} | {s['best25']:.2f} | {s['worst25']:.2f} |")
    return "\n".join(lines)


def figure(result, path, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for row, errors in result["errors"].items():
        e = np.sort(errors[np.isfinite(errors)])
        ax.plot(e, np.arange(1, len(e) + 1) / len(e), label=f"{row} (mean {e.mean():.2f})")
    ax.set_xscale("log")
    ax.set_xlabel("angular error of the estimated illuminant (degrees)")
    ax.set_ylabel("fraction of test images")
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--charts", required=True, help="chart CSV of the real camera (test data)")
    parser.add_argument("--profile", required=True, help="sensor profile with the camera's Adobe matrix")
    parser.add_argument("--figure", help="write the error CDFs here (PNG)")
    parser.add_argument("--train-per-fold", type=int, default=TRAIN_PER_FOLD)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    result = run(args.charts, args.profile, train_per_fold=args.train_per_fold, seed=args.seed)
    print(f"\nilluminant estimation on {result['n_images']} real charts ({Path(args.charts).name}), "
          f"3-fold, {result['train_per_fold']} synthetic charts per fold; angular error in degrees\n")
    print(table(result))
    scored = {s["n"] for s in result["statistics"].values()}
    print(f"\nscored images: {', '.join(map(str, sorted(scored)))} of {result['n_images']} "
          f"(an image without any usable chromatic patch has no estimate)")
    if args.figure:
        figure(result, args.figure, f"Trained on synthetic charts, tested on {Path(args.charts).stem}")
        print(f"\nfigure: {args.figure}")
    print(f"({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
