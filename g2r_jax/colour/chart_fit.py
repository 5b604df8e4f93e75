"""The camera's colour model against measured charts: simulate, score, refit (issue 10).

A profile predicts the raw RGB a camera records for a known surface under a known light: the
surface's linear sRGB c (D65-referred) goes through `unprocess` with the image's measured neutral n,

    raw(c) = diag(n / max n) . S(xy(n)) . c,   S = rownorm(XYZ_D65toCamera(xy) . M_sRGB)

(`unprocess.matrix_srgb_to_white_balanced_camera`; xy(n) is the DNG neutral -> white fixed
point). `predict_patches` is that closed form, vmapped over images (checked against
`unprocess_batch` in the tests); `g2r_jax.pipeline.simulate_patches` runs `unprocess_batch` itself
on a chart image (`chart_image`).

**Refit.** `refit_colour_matrices` fits a ColorMatrix pair (CalibrationIlluminant 17 / 21:
Standard Light A / D65, interpolated in mired as the DNG specification does) by Levenberg-
Marquardt (optimistix) on the unit-vector differences between predicted and measured patch RGB
(an angular loss, scale-free, so no exposure is fitted). The white stays exact: a neutral input
maps to the image's neutral for any matrix (S's rows sum to 1). The pair is written as DNG tags
(ColorMatrix1/2, CameraCalibration and AnalogBalance unchanged; a ForwardMatrix pair, if the
profile had one, is dropped since it would override the refitted matrices in a renderer), so a
DNG renderer given the file's AsShotNeutral still returns the input: `unprocess` inverts exactly
the DNG colour model that the new tags define. Each matrix is scaled so that its calibration
illuminant's white (Y = 1) has a largest camera channel of 1, Adobe's convention.

Angular error between RGB vectors is the colour-constancy metric of Hordley & Finlayson (2006);
chromatic patches are 1-18 of the ColorChecker, neutral 19-24.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from g2r_jax.colour import charts as _charts
from g2r_jax.colour import conversions as _colour
from g2r_jax.colour import dng_model as _dng
from g2r_jax.measure import angular_error_degrees
from g2r_jax.runtime.x64 import enable_x64
from g2r_jax.colour.camera_rgb import matrix_srgb_to_white_balanced_camera

CHART_TILE = 2          # pixels per patch side in the simulated chart image (one 2x2 CFA tile)
REFIT_ILLUMINANTS = (17, 21)   # Standard Light A, D65: the usual DNG pair


# ------------------------------------------------------------------------------------ prediction

def _white_xy(neutral, model: _dng.DngColourModel):
    """The DNG white xy of `neutral` (`dng.camera_neutral_to_xy`), with the derivative of the
    fixed point w = h(w, model) by the implicit function theorem written out for the scalar
    interpolation weight w: dw = h_model / (1 - h_w) (h: weight of the white at weight w)."""
    frozen = jax.tree_util.tree_map(jax.lax.stop_gradient, model)
    xy0, _ = _dng.camera_neutral_to_xy(jax.lax.stop_gradient(neutral), frozen, throw=False)
    w0 = jax.lax.stop_gradient(_dng.interpolation_weight(_colour.xy_to_CCT(xy0), frozen))

    def h(w, m):
        return _dng.interpolation_weight(_colour.xy_to_CCT(_dng._xy_at_weight(w, neutral, m)), m)

    slope = jax.lax.stop_gradient(jax.grad(h)(w0, frozen))
    moved = h(w0, model)
    weight = w0 + (moved - jax.lax.stop_gradient(moved)) / (1.0 - slope)
    return _dng._xy_at_weight(weight, neutral, model)


def _predict_one(neutral, chart_linear, model: _dng.DngColourModel):
    neutral = neutral / neutral[1]
    xy = _white_xy(neutral, model)
    srgb_to_wb_camera = matrix_srgb_to_white_balanced_camera(xy, neutral, model)
    return (chart_linear @ srgb_to_wb_camera.T) * (neutral / jnp.max(neutral))


@jax.jit
def predict_patches(model: _dng.DngColourModel, neutrals, chart_linear):
    """Raw RGB (N, P, 3) that the DNG colour model `model` predicts for chart colours
    `chart_linear` (P, 3, linear sRGB) under each neutral (N, 3): `unprocess` without noise,
    exposure or highlight easing, white reaching max(n)/max(n) = 1 in its strongest channel."""
    return jax.vmap(lambda n: _predict_one(n, chart_linear, model))(neutrals)


def chart_image(chart_srgb) -> np.ndarray:
    """A (4T, 6T, 3) image of the 24 patches in chart order (6 columns x 4 rows), T = CHART_TILE."""
    patches = np.asarray(chart_srgb, np.float32).reshape(4, 6, 3)
    return np.repeat(np.repeat(patches, CHART_TILE, axis=0), CHART_TILE, axis=1)


# ------------------------------------------------------------------------------------- scoring

def patch_errors(predicted, charts: _charts.ChartSet) -> np.ndarray:
    """Angular error (N, 24) in degrees between predicted and measured patch RGB (NaN where unusable)."""
    return angular_error_degrees(predicted, charts.patches, invalid="nan")


def summarise(errors) -> dict:
    """mean / median / p95 over chromatic patches (1-18), mean over neutral ones (19-24), and
    the per-patch median, of an (N, 24) error table (NaN ignored)."""
    chromatic = errors[:, _charts.CHROMATIC]
    chromatic = chromatic[np.isfinite(chromatic)]
    if not chromatic.size:
        raise ValueError("no chromatic patch (1..18) has both a measured and a predicted value: nothing to compare")
    neutral = errors[:, _charts.NEUTRAL]
    return {"chromatic_mean": float(np.mean(chromatic)), "chromatic_median": float(np.median(chromatic)),
            "chromatic_p95": float(np.percentile(chromatic, 95)),
            "neutral_mean": float(np.nanmean(neutral)),
            "patch_median": np.nanmedian(errors, axis=0).tolist(), "n_images": int(errors.shape[0])}


def predict_patches_np(model, charts: _charts.ChartSet, chart_linear=None) -> np.ndarray:
    """`predict_patches` in float64 for the measured neutrals of `charts`: (N, 24, 3)."""
    chart_linear = _charts.chart_linear_srgb() if chart_linear is None else chart_linear
    with enable_x64():
        model64 = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float64) if isinstance(a, jax.Array) else a, model)
        return np.asarray(predict_patches(model64, jnp.asarray(charts.illuminant, jnp.float64),
                                          jnp.asarray(chart_linear, jnp.float64)))


def colour_model_errors(model, charts: _charts.ChartSet, chart_linear=None) -> np.ndarray:
    """`patch_errors` (N, 24) of `predict_patches` (float64) for a colour model."""
    return patch_errors(predict_patches_np(model, charts, chart_linear), charts)


# --------------------------------------------------------------------------------------- refit

def _normalise_to_white(matrix, code):
    """Scale an XYZ->camera matrix so its calibration white (Y = 1) has a largest channel of 1."""
    x, y = {17: _colour.XY_A, 21: _colour.XY_D65}.get(code, None) if code in (17, 21) else \
        _colour.CCT_to_xy(_dng.calibration_illuminant_cct(code))[0]
    response = matrix @ np.array([x / y, 1.0, (1.0 - x - y) / y])
    return matrix / np.max(response)


PAD_IMAGES = 64
_SOLVER = optx.LevenbergMarquardt(rtol=1e-6, atol=1e-8)


def _refit_residuals(pair, args):
    """Unit-vector differences predicted - measured (masked), for `refit_colour_matrices`."""
    neutrals, chart, target, mask, template = args
    model = eqx.tree_at(lambda m: m.color_matrix, template, pair)
    predicted = predict_patches(model, neutrals, chart)
    unit = predicted / jnp.linalg.norm(predicted, axis=-1, keepdims=True)
    return ((unit - target) * mask).reshape(-1)


def refit_colour_matrices(colour_model: _dng.DngColourModel, charts: _charts.ChartSet, *,
                          calibration_illuminants=REFIT_ILLUMINANTS, chart_linear=None,
                          patches=None, max_steps: int = 60, dtype=np.float32):
    """A ColorMatrix pair fitted to measured charts (module docstring).

    **Arguments:** `colour_model`: the starting model (its interpolated matrix at each image's
    white is the initial guess for both); `charts`: the fit images; `calibration_illuminants`:
    EXIF codes of the pair; `patches`: 0-based patch indices in the loss (default all 24; NaN
    patches are skipped); `max_steps`: Levenberg-Marquardt steps.

    **Returns:** `(DngColourModel, calibration_illuminants)` with the fitted pair.
    """
    chart_linear = _charts.chart_linear_srgb() if chart_linear is None else np.asarray(chart_linear)
    patches = np.arange(_charts.N_PATCHES) if patches is None else np.asarray(patches)
    measured = np.asarray(charts.patches, np.float64)[:, patches]
    valid = np.all(np.isfinite(measured), axis=-1)
    unit_measured = np.where(valid[..., None], measured, 1.0)
    unit_measured = unit_measured / np.linalg.norm(unit_measured, axis=-1, keepdims=True)
    codes = tuple(int(c) for c in calibration_illuminants)
    ccts = [_dng.calibration_illuminant_cct(c) for c in codes]
    with enable_x64():
        start = np.asarray(colour_model.color_matrix, np.float64)
        balance = np.asarray(colour_model.analog_balance, np.float64)
        calibration = np.asarray(colour_model.camera_calibration, np.float64)
        if len(set(ccts)) == 1 or start.shape[0] != 2:
            raise ValueError(f"need two calibration illuminants of different CCT, got {codes}")
        initial = start[np.argsort(np.asarray(colour_model.calibration_cct))]
        order = np.argsort(ccts)
        template = _dng.DngColourModel.from_tags(list(codes), list(initial[np.argsort(order)]),
                                                 list(calibration[np.argsort(order)]), (), balance, dtype=np.float64)
        neutrals = jnp.asarray(charts.illuminant, jnp.float64)
        chart = jnp.asarray(chart_linear[patches], jnp.float64)
        target, mask = jnp.asarray(unit_measured), jnp.asarray(valid[..., None], jnp.float64)

        # pad the images to a multiple of PAD_IMAGES (masked out) so that fits on folds of
        # slightly different sizes reuse one compiled solver
        padded = -(-len(neutrals) // PAD_IMAGES) * PAD_IMAGES
        extra = padded - len(neutrals)
        neutrals = jnp.concatenate([neutrals, jnp.ones((extra, 3), jnp.float64)])
        target = jnp.concatenate([target, jnp.ones((extra,) + target.shape[1:], jnp.float64)])
        mask = jnp.concatenate([mask, jnp.zeros((extra,) + mask.shape[1:], jnp.float64)])
        args = (neutrals, chart, target, mask, template)
        solution = optx.least_squares(_refit_residuals, _SOLVER, jnp.asarray(initial), args=args,
                                      max_steps=max_steps, throw=False)
        pair = np.asarray(solution.value)
    pair = np.stack([_normalise_to_white(pair[i], int(np.asarray(codes)[order][i])) for i in range(2)])
    fitted = _dng.DngColourModel.from_tags(np.asarray(codes)[order].tolist(), list(pair),
                                           list(calibration), (), balance, dtype=dtype)
    return fitted, tuple(int(c) for c in np.asarray(codes)[order])


def as_pair(colour_model: _dng.DngColourModel, calibration_illuminants) -> _dng.DngColourModel:
    """A one-matrix model written as a pair at REFIT_ILLUMINANTS (same matrix twice): the
    same predictions, a starting point for `refit_colour_matrices`."""
    if len(set(np.asarray(colour_model.calibration_cct).tolist())) == 2:
        return colour_model
    matrix = np.asarray(colour_model.color_matrix[0], np.float64)
    calibration = np.asarray(colour_model.camera_calibration[0], np.float64)
    return _dng.DngColourModel.from_tags(REFIT_ILLUMINANTS, [matrix, matrix], [calibration, calibration], (),
                                         np.asarray(colour_model.analog_balance), dtype=np.float64)


def with_colour(profile, colour_model, calibration_illuminants, note: str = ""):
    """`profile` with another colour model (and its calibration illuminant codes)."""
    import dataclasses

    info = dataclasses.replace(profile.info, calibration_illuminants=tuple(int(c) for c in calibration_illuminants),
                               provenance=(profile.info.provenance + (" " if profile.info.provenance else "") + note).strip())
    return dataclasses.replace(profile, colour=colour_model, info=info)   # info is static: not a tree_at leaf


def cross_validated_refit(profile, charts: _charts.ChartSet, folds, *, chart_linear=None, max_steps: int = 60,
                          progress=None) -> dict:
    """Refit on all folds but one, score on the one left out, for each fold.

    **Returns:** dict with `before` / `after` (N, 24) held-out angular errors (every image scored
    by a model that did not see it), `fold_before` / `fold_after` (mean chromatic per fold),
    and `models` (the refitted model of each fold).
    """
    say = progress or (lambda message: None)
    folds = np.asarray(folds)
    start = as_pair(profile.colour, profile.info.calibration_illuminants)
    before = colour_model_errors(profile.colour, charts, chart_linear)
    after = np.full_like(before, np.nan)
    fold_before, fold_after, models = [], [], []
    for fold in np.unique(folds):
        test, train = folds == fold, folds != fold
        say(f"refitting the colour matrices on {int(train.sum())} images (fold {fold} held out)")
        model, _ = refit_colour_matrices(start, charts.subset(train), chart_linear=chart_linear, max_steps=max_steps)
        after[test] = colour_model_errors(model, charts.subset(test), chart_linear)
        fold_before.append(summarise(before[test])["chromatic_mean"])
        fold_after.append(summarise(after[test])["chromatic_mean"])
        models.append(model)
    return {"before": before, "after": after, "fold_before": fold_before, "fold_after": fold_after, "models": models}


def rendered_delta_E(colour_model, charts: _charts.ChartSet, chart_linear=None) -> np.ndarray:
    """CIEDE2000 (N, 24) between the measured patches as a DNG renderer shows them and the chart.

    The renderer's white balance: camera RGB -> XYZ_D50 by CameraToXYZ_D50 at the white of the
    image's measured neutral (AsShotNeutral), Bradford D50 -> D65 (`dng.matrix_XYZ_D65_to_camera`
    inverted); one exposure scale per image (least squares on Y over the usable neutral patches);
    CIE Lab under D65 against the chart's XYZ (colour-science `delta_E`, CIE 2000). NaN where unusable.
    """
    import colour

    chart_linear = _charts.chart_linear_srgb() if chart_linear is None else np.asarray(chart_linear)
    with enable_x64():
        model64 = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float64) if isinstance(a, jax.Array) else a,
                                         colour_model)

        def to_xyz(neutral):
            neutral = neutral / neutral[1]
            xy, _ = _dng.camera_neutral_to_xy(neutral, model64, throw=False)
            return jnp.linalg.inv(_dng.matrix_XYZ_D65_to_camera(xy, model64))

        camera_to_xyz = np.asarray(jax.vmap(to_xyz)(jnp.asarray(charts.illuminant, jnp.float64)))
    XYZ = np.einsum("nij,npj->npi", camera_to_xyz, charts.patches)
    XYZ_in = chart_linear @ np.asarray(_colour.MATRIX_SRGB_TO_XYZ).T
    neutral_Y = XYZ[:, _charts.NEUTRAL, 1]
    target_Y = XYZ_in[_charts.NEUTRAL, 1][None]
    usable = np.isfinite(neutral_Y)
    scale = (np.sum(np.where(usable, neutral_Y * target_Y, 0), 1)
             / np.sum(np.where(usable, neutral_Y, 0) ** 2, 1))
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    lab = colour.XYZ_to_Lab(XYZ * scale[:, None, None], white)
    return np.asarray(colour.delta_E(lab, colour.XYZ_to_Lab(XYZ_in, white)[None], method="CIE 2000"))
