"""The content model in the downstream experiment (issue 32, and issue 43: the check measures
the product): row 'fitted' is g2r_jax as `g2r-fit-profile` makes it, the lights fitted to the
training files and a content model on the CG views; row 'single' the same from one training
file; 'upi_content' is UPI on the same adapted views (so that the lead over UPI is measured on
equal content).

The content model is the profile's own when it carries one (used as given). Else it is the one
`g2r-fit-profile` fits (`FITTED`, the 'scenes' family: each CG frame's grey-world cast and
brightness those of one of the real files' scenes, drawn per frame, the casts balanced by the
files' as-shot neutrals), fitted per fold to the
training folds' files only, never the test fold; no label beyond the as-shot neutrals and no
estimator is used to choose it. Protocol and measurement: docs/pages/validation/content_model.md.

For the benchmark's comparisons of families (benchmarks/content_model.py --families), a candidate
can also be chosen on the training folds (`fold_content_model`): they are split again (two thirds
/ one third, seeded, files with the same pixels kept together: `g2r_jax.measure.folds_of`); each
candidate makes g2r_jax RAW of the CG views under lights fitted to the inner two thirds, the
selection estimator is trained on it and tested on the inner third, and the candidate with the
lowest mean angular error is kept, then refitted to all the training folds.

Candidates are named 'identity', a family fitted to the real thumbnails' statistics without labels
('chroma', 'chroma_tone', 'cast': `g2r_jax.content.fit_content_model`), 'chroma@S' a chroma
scale S given, or 'cast@C' a share C of each frame's cast kept, the rest taken to neutral.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from g2r_jax.downstream.base.product import FITTED, adapted_views, candidate_model

# The candidates the measurement kept: on the nine NUS cameras (200 views, seed 0) the selection
# over identity, the fitted 'chroma' and these two scales kept 0.35 on 22 of 27 folds and 0.5 on
# the others; the fitted 'chroma' is the identity on every camera and 'chroma_tone' made the
# selection estimator worse (docs/pages/validation/content_model.md, findings 1 and 2).
CANDIDATES = ("identity", "chroma@0.5", "chroma@0.35")
SELECTION_ESTIMATOR = "moments"   # the estimator the page's selection used (cheap to train)
INNER_FOLDS = 3                   # the training folds split into thirds: one third validates


@dataclasses.dataclass(frozen=True)
class FoldChoice:
    """The content model one fold uses: `model`, the candidate `name` it came from, and the
    selection's mean inner-third error per candidate (degrees; empty when given, not chosen)."""

    model: object
    name: str
    errors: dict


def inner_split(train: np.ndarray, groups, seed: int, fold: int) -> tuple:
    """(inner training indices, inner validation indices), both subsets of `train`: one seeded
    third of `train` validates, files with the same pixels (`groups`, indexed like the whole set)
    on one side."""
    from g2r_jax.measure import folds_of

    inner = folds_of(len(train), INNER_FOLDS, 10_000 + 100 * seed + fold,
                     groups=None if groups is None else np.asarray(groups)[train])
    validate = train[inner[0]]
    return np.setdiff1d(train, validate), validate


def select_candidate(candidates, real, train: np.ndarray, views: np.ndarray, profile, fit_lights, *,
                     estimator: str = SELECTION_ESTIMATOR, seed: int, fold: int) -> tuple:
    """The candidate whose g2r_jax set trains `estimator` best on an inner third of `train`.

    **Arguments:** `candidates` (names, see the module docstring); `real`: the `RealSet`; `train`:
    the indices of the training folds (the only images read); `views`: the CG views (linear sRGB);
    `profile`: the camera's profile (its colour model for the fitted families);
    `fit_lights(lights) -> profile` with its illuminant model fitted to `lights` (N, 3).
    **Returns:** (the kept name, {name: mean inner-third error, degrees})."""
    from g2r_jax.downstream.base import training_sets
    from g2r_jax.downstream.illuminant.estimators import train_estimator
    from g2r_jax.measure import angular_error_degrees

    inner_train, validate = inner_split(train, getattr(real, "groups", None), seed, fold)
    lights = real.illuminants[inner_train]
    fitted = fit_lights(lights)
    errors = {}
    for name in candidates:
        model = candidate_model(name, real.images[inner_train], lights, views, profile)
        images, labels = training_sets.g2r_set(adapted_views(model, views, 7_000 + 1000 * seed + fold), fitted,
                                                 7_000 + 1000 * seed + fold)
        predict = train_estimator(estimator, images, labels, seed=1000 * seed + fold)
        errors[name] = float(np.mean(angular_error_degrees(predict(real.images[validate]),
                                                           real.illuminants[validate])))
    return min(errors, key=errors.get), errors


def fold_content_model(real, train: np.ndarray, views: np.ndarray, profile, fit_lights, *,
                       candidates=CANDIDATES, estimator: str = SELECTION_ESTIMATOR, seed: int,
                       fold: int) -> FoldChoice:
    """The candidate `select_candidate` keeps, refitted to all the training folds' thumbnails."""
    name, errors = select_candidate(candidates, real, train, views, profile, fit_lights, estimator=estimator,
                                    seed=seed, fold=fold)
    model = candidate_model(name, real.images[train], real.illuminants[train], views, profile)
    return FoldChoice(model=model, name=name, errors=errors)


def _note(sets, line: str) -> None:
    if line not in sets.notes:
        sets.notes.append(line)


def fold_choice(sets, train: np.ndarray, fold: int, seed: int) -> FoldChoice:
    """The content model of (fold, seed), cached in `sets.cache` ('fitted' and 'upi_content' share it): the
    profile's own as given, else `FITTED` fitted to the training folds' files; each is said in
    `sets.notes`."""
    key = ("content_model", fold, seed)
    if key in sets.cache:
        return sets.cache[key]
    own = getattr(sets.profile, "content", None)
    if own is not None:
        choice = FoldChoice(model=own, name="the profile's", errors={})
        _note(sets, f"g2r_jax rows: the profile's own content model ({own.family}, chroma scale "
                    f"{float(own.chroma_scale):.2f}, tone power {float(own.tone_power):.2f}), used as given (no selection)"
                    + ("; it applies by default, so the shipped row carries it too" if own.apply_by_default else ""))
    else:
        from g2r_jax.content import describe

        model = candidate_model(FITTED, sets.real.images[train], sets.real.illuminants[train], sets.views(seed),
                                sets.profile)
        choice = FoldChoice(model=model, name=FITTED, errors={})
        _note(sets, f"content model of the g2r_jax rows, seed {seed}, fold {fold + 1}: {describe(model)}, fitted to the "
                    f"{len(train)} training files' scenes (no estimator chose it)")
    sets.cache[key] = choice
    return choice


def _adapted(sets, train, fold, seed):
    """The fold's adapted views; only the last (fold, seed) is kept (a set of views is large)."""
    key = ("content_views", fold, seed)
    cached = sets.cache.get(("content_views",))
    if cached is None or cached[0] != key:
        model = fold_choice(sets, train, fold, seed).model
        sets.cache[("content_views",)] = (key, adapted_views(model, sets.views(seed), 1000 * seed + 10 * fold + 5))
    return sets.cache[("content_views",)][1]


def prepare(sets, train: np.ndarray, fold: int, seed: int) -> None:
    """Make the fold's content model and adapted views before rows that share them are built
    side by side (`experiment._Sets.prepare`)."""
    _adapted(sets, train, fold, seed)


def content_row(sets, train: np.ndarray, fold: int, seed: int):
    """Row 'fitted', the product: the lights fitted to the training files (`sets.fitted`) on the
    views adapted by the fold's content model (`fold_choice`); the 'fitted_no_content' control
    has the same lights, noise and seed on the views as they are. The model is applied here
    once: the profile goes to the simulation without it."""
    from g2r_jax.downstream.base import training_sets
    from g2r_jax.pipeline import without_content

    fitted = without_content(sets.fitted(train, fold, seed))
    return training_sets.g2r_set(_adapted(sets, train, fold, seed), fitted, 1000 * seed + 10 * fold + 4)


def one_file_row(sets, profile, index: int, salt: int, seed: int):
    """Row 'single': g2r_jax as `g2r-fit-profile` makes it from the one file `index`: `profile`
    with the lights fitted to its as-shot neutral, and the content model of its scene
    (the profile's own when it carries one; one file weighs about 1 % against the prior of real
    scenes, `content.fitting.files_weight`); without a model when its cast cannot be fitted, as
    `g2r-fit-profile` then writes none."""
    from g2r_jax.downstream.base import training_sets
    from g2r_jax.pipeline import without_content

    real, one = sets.real, slice(index, index + 1)
    model = getattr(sets.profile, "content", None)
    if model is None:
        try:
            model = candidate_model(FITTED, real.images[one], real.illuminants[one], sets.views(seed), sets.profile)
        except ValueError as error:
            _note(sets, f"one-DNG row, seed {seed}: no content model from file {index} ({error})")
            return training_sets.g2r_set(sets.views(seed), profile, salt)
    return training_sets.g2r_set(adapted_views(model, sets.views(seed), salt), without_content(profile), salt)


def upi_content_row(sets, train: np.ndarray, fold: int, seed: int):
    """Row 'upi_content': the 'upi' row's recipe and seed on the same adapted views (sRGB-coded)."""
    from g2r_jax.downstream.base import training_sets

    views = training_sets.linear_to_srgb_views(_adapted(sets, train, fold, seed))
    return training_sets.upi_set(views, seed + 1)


BUILDERS = {"fitted": content_row, "upi_content": upi_content_row}
