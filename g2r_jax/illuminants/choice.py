"""Which illuminant model a profile gets, fitted, with a one-line reason.

`choose_illuminant_model` fits the model a user names (`KINDS`) or, for 'auto', the one the
downstream measurement chose: an illuminant estimator trained on real images relit to lights drawn
from each model, tested on the real NUS images (docs/pages/validation/illuminant_models.md).
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np

from g2r_jax.illuminants import distributions as _distributions
from g2r_jax.illuminants import kernel as _kernel

PRIOR_KINDS = {"prior": "day", "prior-night": "night", "prior-day-night": "day_night"}
KINDS = ("auto", "kernel", "pooled", "gaussian", "mixture", "locus", *PRIOR_KINDS)
MIN_LIGHTS_FOR_KERNEL = 10     # 'auto': the kernel model from this many distinct measured lights, else 'pooled'
LOCUS_CCT_RANGE = (2000.0, 20000.0)   # the camera's Planckian locus giving the kernels' directions
MEASUREMENT = "docs validation/illuminant_models"
PRESET_EVIDENCE = 3.0   # nats: a Bayes factor of e^3 ~ 20, "strong" (Kass & Raftery, JASA 90, 1995, sec. 3.2)
# Another preset than day also needs this many distinct lights and its median light favouring it by
# PRESET_MEDIAN_EVIDENCE nats: with the total alone, random sets of the NUS cameras' day and indoor lights
# took a night preset 2.5-6 % of the time (n 1-9), up to 14 % on one camera; with the median rule 0.6 %
# at 3 lights (1.3 % on one camera), 0.08 % at 5 (0.3 %), 0 at 9, while the S20 FE's night lights keep it
# 96 % of the time at 5 and 99 % at 9 (benchmarks/prior_presets.py; docs validation/illuminant_models,
# "Which prior preset").
MIN_LIGHTS_FOR_PRESET = 5
PRESET_MEDIAN_EVIDENCE = 1.0


class LightShares(NamedTuple):
    """Where an illuminant model's probability comes from: the `lights` distinct measured lights
    (the files') with total weight `files` (0 to 1), the rest (`rest` = 1 - files) from `other`
    (words: the pooled lights of K other cameras, the cross-camera prior, the calibration locus;
    '' for a model of the lights alone); `sources`: the pooled model's source cameras."""

    lights: int
    files: float
    other: str
    sources: tuple = ()

    @property
    def rest(self) -> float:
        return 1.0 - self.files


class IlluminantChoice(NamedTuple):
    """The fitted model, why it was chosen (one line, which states the `shares`), how many distinct
    measured lights it saw and how much of the model they weigh (`LightShares`)."""

    model: _distributions.IlluminantModel
    reason: str
    lights: int
    shares: LightShares | None = None


def shares_words(shares: LightShares) -> str:
    """'lights: N distinct measured lights weigh X %, <other> Y %' (X + Y = 100 as printed; the
    other part left out for a model of the lights alone)."""
    files = round(100 * shares.files)
    one = shares.lights == 1
    head = f"lights: {shares.lights} distinct measured light{'' if one else 's'} weigh{'s' if one else ''} {files} %"
    return f"{head}, {shares.other} {100 - files} %" if shares.other else head


def _blend_shares(n: int, other: str, sources=()) -> LightShares:
    """The shares of n lights' kernels blended with a base measure (`kernel.fit_kernel`:
    n / (n + n0) on the lights, `kernel.prior_share` on the base)."""
    return LightShares(n, 1.0 - _kernel.prior_share(n), other, tuple(sources))


def _pooled_words(sources) -> str:
    return f"the pooled lights of {len(sources)} other camera{'' if len(sources) == 1 else 's'}"


PRIOR_WORDS = "the cross-camera prior"      # the base measure of 'kernel' and all of 'prior'
LOCUS_WORDS = "the calibration matrices' locus"


def _chosen(model, why: str, shares: LightShares, words: str) -> IlluminantChoice:
    """The choice whose reason is '<why>: <shares>; <words>' (the shares early, so that a line cut
    short still carries them)."""
    return IlluminantChoice(model, f"{why}: {shares_words(shares)}; {words}", shares.lights, shares)


def distinct_lights(chromaticities) -> np.ndarray:
    """(N, 2) distinct (to 1e-9) finite lights (r/g, b/g) of `chromaticities`."""
    points = np.asarray(chromaticities, np.float64).reshape(-1, 2)
    points = points[np.all(np.isfinite(points), axis=1)]
    return np.unique(np.round(points, 9), axis=0)


def _hull_possible(points) -> bool:
    if len(points) < 3:
        return False
    try:
        _distributions.convex_hull_halfplanes(points)
    except ValueError:
        return False
    return True


def camera_locus_tangents(points, colour_model) -> np.ndarray:
    """Unit tangents of the camera's Planckian locus (`LOCUS_CCT_RANGE`, through its DNG colour
    model) nearest each light; the x axis where the matrices give too few usable locus points."""
    locus = _distributions.locus_chromaticities(colour_model, 64, LOCUS_CCT_RANGE)
    locus = locus[np.all(np.isfinite(locus) & (locus > 0), axis=1)]
    if len(locus) < 2:
        return np.tile([1.0, 0.0], (len(points), 1))
    return _kernel.locus_tangents(points, locus)


def _best_prior_preset(points, colour_model, dtype):
    """(preset, `prior.CameraPrior`) of the prior preset under which the lights are most likely:
    the day preset unless, from `MIN_LIGHTS_FOR_PRESET` lights, another one's log likelihood of all
    the lights is `PRESET_EVIDENCE` nats higher and that of the median light `PRESET_MEDIAN_EVIDENCE`
    higher (without these rules day and indoor lights took the night preset a few % of the time);
    the day preset for fewer lights. A preset this camera's matrices cannot carry (`prior.camera_prior`
    refuses it) is not a candidate; ValueError only when none is."""
    from g2r_jax.illuminants.prior import DEFAULT_PRESET, camera_prior

    best, refusals = None, []
    for preset in dict.fromkeys([DEFAULT_PRESET, *PRIOR_KINDS.values()]):
        try:
            mapped = camera_prior(colour_model, preset, dtype=dtype)
        except ValueError as error:
            refusals.append(str(error))
            continue
        per_light = np.asarray(_distributions.mixture_log_likelihood(mapped.model, points)) if len(points) \
            else np.zeros(0)
        if best is None:
            best = (per_light, preset, mapped)
        elif (len(points) >= MIN_LIGHTS_FOR_PRESET and np.sum(per_light - best[0]) > PRESET_EVIDENCE
              and np.median(per_light - best[0]) > PRESET_MEDIAN_EVIDENCE):
            best = (per_light, preset, mapped)
    if best is None:
        raise ValueError("; ".join(refusals))
    return best[1], best[2]


def _prior_words(preset: str, mapped) -> str:
    from g2r_jax.illuminants.prior import left_out_words

    left_out = left_out_words(mapped.left_out, preset)
    return f"{preset} preset" + (f"; {left_out}" if left_out else "")


def _count(n: int) -> str:
    return f"{n} measured light{'' if n == 1 else 's'}"


def _prior_choice(points, colour_model, kind, why, auto, dtype) -> IlluminantChoice:
    """The cross-camera prior: the preset `kind` names, or for 'auto' the one the lights favour
    (`_best_prior_preset`: day unless the lights are strongly more likely under another)."""
    from g2r_jax.illuminants.prior import camera_prior

    if auto:
        preset, mapped = _best_prior_preset(points, colour_model, dtype)
        chosen = f"{_prior_words(preset, mapped)}, " + ("the lights most likely under it" if len(points)
                                                         else "the default without lights")
    else:
        preset = PRIOR_KINDS[kind]
        mapped = camera_prior(colour_model, preset, dtype=dtype)
        chosen = _prior_words(preset, mapped)
    return _chosen(mapped.model, why, LightShares(len(points), 0.0, PRIOR_WORDS),
                   f"the cross-camera prior of measured scene lights ({chosen}), no measured light used")


def fit_kernel_for_camera(points, colour_model, dtype=np.float32) -> tuple:
    """(model, words) of the kernel model (`kernel.fit_kernel`) of `points` in this camera,
    blended with the prior preset most likely for them."""
    return _fit_kernel(points, colour_model, dtype)[:2]


def _fit_kernel(points, colour_model, dtype) -> tuple:
    """(model, words, `LightShares`) of `fit_kernel_for_camera`."""
    tangents = camera_locus_tangents(points, colour_model)
    preset, mapped = _best_prior_preset(points, colour_model, dtype)
    along, across = _kernel.choose_bandwidths(points, tangents)
    model = _kernel.fit_kernel(points, tangents, prior=mapped.model, bandwidths=(along, across), dtype=dtype)
    share = _kernel.prior_share(len(points))
    how = ("leave-one-out likelihood" if len(points) >= _kernel.MIN_LIGHTS_FOR_CV
           else f"fixed: fewer than {_kernel.MIN_LIGHTS_FOR_CV} lights")
    words = (f"kernel density of the {_count(len(points))} along the camera's Planckian locus "
             f"(bandwidths {along:.3g} along, {across:.3g} across, {how}) with {share:.0%} of the "
             f"cross-camera prior ({_prior_words(preset, mapped)})")
    return model, words, _blend_shares(len(points), PRIOR_WORDS)


def fit_pooled_for_camera(points, colour_model, exclude=(), dtype=np.float32, base=None) -> tuple:
    """(model, words) of the pooled model (`illuminants.pooled`): the kernel density of `points`
    (N >= 0) blended with other cameras' lights carried into this camera (`exclude`: source
    cameras left out, e.g. the camera under test; `base`: a `pooled.pooled_base` to reuse)."""
    return _fit_pooled(points, colour_model, exclude, dtype, base)[:2]


def _fit_pooled(points, colour_model, exclude=(), dtype=np.float32, base=None) -> tuple:
    """(model, words, `LightShares`) of `fit_pooled_for_camera`."""
    from g2r_jax.illuminants.pooled import fit_pooled, pooled_base

    def tangents_of(p):
        return camera_locus_tangents(p, colour_model)

    base = pooled_base(colour_model, tangents_of, exclude) if base is None else base
    points = distinct_lights(points)
    model, words = fit_pooled(points, colour_model, tangents_of, exclude=exclude, dtype=dtype, base=base)
    return model, words, _blend_shares(len(points), _pooled_words(base.sources), base.sources)


def choose_illuminant_model(chromaticities, colour_model, kind: str = "auto", seed: int = 0,
                            dtype=np.float32, exclude=()) -> IlluminantChoice:
    """Fit the illuminant model `kind` (one of `KINDS`) to the measured lights.

    **Arguments:** `chromaticities`: (N, 2) measured scene lights (r/g, b/g), N >= 0;
    `colour_model`: the camera's `DngColourModel` (for the prior, the locus and the kernels'
    directions); `kind`: 'kernel' (`illuminants.kernel`), 'pooled' (`illuminants.pooled`: the
    kernel of the lights on other cameras' lights carried into this one), 'gaussian' (published: one Gaussian and
    the lights' convex hull), 'mixture' (BIC-selected Gaussians and the hull), 'locus' (the
    calibration matrices' CCT locus, supplement S3), 'prior', 'prior-night', 'prior-day-night'
    (`illuminants.prior` with that preset) or 'auto': the kernel model from `MIN_LIGHTS_FOR_KERNEL`
    distinct lights, else 'pooled' (both chosen by the downstream measurement of `MEASUREMENT`),
    or the prior with a night preset where the lights strongly favour one (`_best_prior_preset`);
    `seed`: the mixture's EM initialisation; `exclude`: source cameras of the pool to leave out
    wherever the model is the pooled one ('pooled', or 'auto' below `MIN_LIGHTS_FOR_KERNEL`
    lights; e.g. every camera of a data set under test, `pooled.carried_lights`). Prior lights the
    camera's matrices cannot carry are left out and counted in the reason (`prior.camera_prior`).

    **Returns:** an `IlluminantChoice`; its reason states how much the files' distinct lights weigh
    in the model and how much the rest (`LightShares`, `shares_words`). Raises ValueError for an
    unknown kind, or for 'gaussian' or 'mixture' without 3 distinct, non-collinear lights.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown illuminant model {kind!r}; known: {', '.join(KINDS)}")
    points = distinct_lights(chromaticities)
    n = len(points)
    lights = _count(n)
    auto = kind == "auto"
    if auto:
        if n >= MIN_LIGHTS_FOR_KERNEL:
            model, words, shares = _fit_kernel(points, colour_model, dtype)
            return _chosen(model, f"kernel (auto, {lights} >= {MIN_LIGHTS_FOR_KERNEL}, by the downstream "
                                  f"measurement in {MEASUREMENT})", shares, words)
        preset, mapped = _best_prior_preset(points, colour_model, dtype)
        if preset == "day":
            model, words, shares = _fit_pooled(points, colour_model, exclude, dtype)
            return _chosen(model, f"pooled (auto, {lights} < {MIN_LIGHTS_FOR_KERNEL}, by the downstream "
                                  f"measurement in {MEASUREMENT}; the lights favour no night preset)", shares, words)
        kind, why = "prior", (f"prior (auto, {lights} < {MIN_LIGHTS_FOR_KERNEL} strongly favouring the "
                              f"{preset} preset, which the pooled day lights lack)")
    else:
        why = f"{kind} (asked for; {lights})"
    if kind == "locus":
        return _chosen(_distributions.fit_locus(colour_model, dtype=dtype), why, LightShares(n, 0.0, LOCUS_WORDS),
                       "the calibration matrices' A-D65 CCT locus, no measured light used")
    if kind in PRIOR_KINDS:
        return _prior_choice(points, colour_model, kind, why, auto, dtype)
    if kind == "pooled":
        model, words, shares = _fit_pooled(points, colour_model, exclude, dtype)
        return _chosen(model, why, shares, words)
    if kind == "kernel":
        if n == 0:
            raise ValueError("the kernel illuminant model needs at least one measured illuminant "
                             "(use the prior or the locus model)")
        model, words, shares = _fit_kernel(points, colour_model, dtype)
        return _chosen(model, why, shares, words)
    if not _hull_possible(points):
        raise ValueError(f"the {kind} illuminant model needs at least 3 distinct, non-collinear "
                         f"illuminants; got {n} (use the kernel, the prior or the locus model)")
    alone = LightShares(n, 1.0, "")
    if kind == "gaussian":
        return _chosen(_distributions.fit_gaussian(chromaticities, dtype=dtype), why, alone,
                       "one Gaussian and the lights' convex hull")
    model = _distributions.fit_mixture(chromaticities, seed=seed, dtype=dtype)
    return _chosen(model, why, alone, f"{len(model.weights)} Gaussian(s) by BIC and the lights' convex hull")
