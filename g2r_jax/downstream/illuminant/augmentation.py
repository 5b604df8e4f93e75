"""Augmentation: an illuminant estimator trained on a user's labelled real files together with
synthetic RAW (g2r_jax, or UPI for comparison), the recipe chosen on the real files alone (issue 48).

Recipes (`Recipe`):
- `real`: the real files alone (what the user has without synthetic RAW);
- `mixed` k: real and synthetic images pooled, the synthetic set counted as k real files: each
  real image weighs 1, the synthetic set k in all (k / n_synthetic each), so that its share of the
  training signal is k / (k + n_real) and shrinks as real files are added: a recipe chosen on two
  thirds of the files keeps its meaning when retrained on all of them (a share fixed instead
  overweighted the synthetic set after the retraining: a first smoke run, NikonD40, moments, one
  seed, all files: +5 % over real alone). The closed forms' least squares take these weights
  (`estimators.train_moments` / `train_histogram` `weights`); the CNN's crops draw their images by
  them, its checkpoints judged on real images only;
- `pretrained` (CNN): trained on the synthetic set, then fine-tuned on the real files at a third of
  the learning rate (the usual transfer schedule; Yosinski et al., "How transferable are features
  in deep neural networks?", NeurIPS 2014);
- `synthetic`: the synthetic set alone, the real files only choosing it (with ten files g2r_jax
  alone beat both real alone and every combination tried: docs/pages/validation/augmentation.md).

The choice (`choose`): K-fold cross-validation on the real training files (`folds`: 3 for the CNN,
10 for the closed forms, at most one part per distinct file): their distinct
images (duplicates kept together) are split by a seeded permutation into K parts; every candidate
is trained on K - 1 parts (with all the synthetic images) and scored on the part left out, so
that every real file is scored once, by a network that did not see it (one held-out third, the
first protocol, scored three images of ten files and chose real alone in 38 of 81 trainings where
g2r_jax alone was 18 % better on the test folds). A candidate replaces `real` only when it beats
it by more than one standard error of the paired per-image differences over all the real files
(`MARGIN`: a gain the files can tell from noise); `synthetic` so chosen becomes the base that a
combination must beat the same way (`_clear_winner`); among the combinations that do, the lowest
mean wins; the winner is retrained on all the real training files. So the combination is worse than real alone only by
what the files cannot tell. With fewer than `MIN_FILES` distinct real files no part can be left
out: the recipe is then `FEW_FILES` (stated in the result, not chosen).
The test fold of the experiment is never seen.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from g2r_jax.measure import angular_error_degrees, duplicate_groups

__all__ = ["Recipe", "AugmentedSet", "candidates", "train", "choose", "train_chosen", "MIN_FILES", "FEW_FILES", "folds", "REAL", "SYNTHETIC"]

FINE_TUNE_RATE = 1 / 3     # the fine-tuning learning rate, a share of the estimator's own
FOLDS = {"cnn": 3}         # cross-validation folds that choose the recipe: the CNN's candidates are trainings
CLOSED_FORM_FOLDS = 10     # the closed forms' are cheap: each candidate sees 90 % of the files, not 67 %
MIN_FILES = 6              # distinct real files needed to leave parts out (two in each of three)
MARGIN = 1.0               # standard errors of the paired differences a recipe must beat real alone by


@dataclasses.dataclass(frozen=True)
class Recipe:
    """How real and synthetic images are combined: `kind` 'real', 'mixed' or 'pretrained'; `worth`
    the number of real files the synthetic set counts as in a 'mixed' set."""

    kind: str
    worth: float = 0.0

    def __str__(self) -> str:
        if self.kind == "mixed":
            return f"mixed, g2r_jax as {self.worth:g} files"
        return "g2r_jax alone" if self.kind == "synthetic" else self.kind


REAL = Recipe("real")
SYNTHETIC = Recipe("synthetic")
FEW_FILES = Recipe("mixed", 30)    # the first measurement: g2r_jax alone was worth about 30 labelled files


@dataclasses.dataclass(frozen=True)
class AugmentedSet:
    """A training set of an augmented row: `real` and `synthetic`, each (images, illuminants)."""

    real: tuple
    synthetic: tuple


def candidates(estimator: str) -> tuple:
    """The recipes tried for `estimator`: real alone, the synthetic set alone, and the synthetic set
    worth 10, 30, 100 or 300 files for the closed forms (cheap; about 30 was g2r_jax alone's worth
    in the issue's first measurement), worth 30 and pretraining for the CNN (each candidate is a
    training per cross-validation fold)."""
    if estimator == "cnn":
        return (REAL, SYNTHETIC, Recipe("mixed", 30), Recipe("pretrained"))
    return (REAL, SYNTHETIC) + tuple(Recipe("mixed", k) for k in (10, 30, 100, 300))


def _mixed_weights(n_real: int, n_synthetic: int, worth: float) -> np.ndarray:
    return np.r_[np.ones(n_real), np.full(n_synthetic, worth / n_synthetic)]


def train(estimator: str, data: AugmentedSet, recipe: Recipe, *, seed: int = 0, synthetic=None):
    """One estimator trained by `recipe` on `data`. `synthetic`: the predictor the 'synthetic'
    recipe trains on `data` with this `seed`, when already trained (it is that recipe's result and
    the 'pretrained' recipe's first network: not trained again). **Returns:** a predictor (images
    -> lights)."""
    from g2r_jax.downstream.illuminant import estimators

    real_images, real_lights = data.real
    if recipe.kind == "real":
        return estimators.train_estimator(estimator, real_images, real_lights, seed=seed)
    synthetic_images, synthetic_lights = data.synthetic
    if recipe.kind == "synthetic":
        if synthetic is not None:
            return synthetic
        return estimators.train_estimator(estimator, synthetic_images, synthetic_lights, seed=seed)
    if recipe.kind == "pretrained":
        if estimator != "cnn":
            raise ValueError(f"recipe 'pretrained' is for the CNN, not {estimator!r}")
        config = estimators.CnnConfig()
        first = synthetic if synthetic is not None else estimators.train_cnn(
            synthetic_images, synthetic_lights, seed=seed, config=config)
        tuned = dataclasses.replace(config, learning_rate=config.learning_rate * FINE_TUNE_RATE)
        return estimators.train_cnn(real_images, real_lights, seed=seed, config=tuned, init=first.params)
    if recipe.kind != "mixed":
        raise ValueError(f"unknown recipe {recipe.kind!r}; expected real, synthetic, mixed or pretrained")
    images = estimators.joined([real_images, synthetic_images])
    lights = np.concatenate([np.asarray(real_lights, np.float64), np.asarray(synthetic_lights, np.float64)])
    weights = _mixed_weights(len(real_images), len(synthetic_images), recipe.worth)
    if estimator == "cnn":
        is_real = np.r_[np.ones(len(real_images), bool), np.zeros(len(synthetic_images), bool)]
        return estimators.train_cnn(images, lights, seed=seed, sampling=weights, validation_from=is_real)
    return estimators.train_estimator(estimator, images, lights, seed=seed, weights=weights)


def folds(estimator: str) -> int:
    """K of the choice's cross-validation for `estimator`. Every candidate is scored after training
    on (K - 1) / K of the files and the winner retrained on all: a bias against `real`, whose error
    still falls with more files where the synthetic set's does not (with all the NUS files, 3 folds
    chose the synthetic set for the histogram estimator where real alone was better on the test
    folds: docs/pages/validation/augmentation.md). More folds shrink it; the CNN pays a training per
    fold and keeps 3."""
    return FOLDS.get(estimator, CLOSED_FORM_FOLDS)


def _cross_validation_parts(images: np.ndarray, seed: int, k: int = 3) -> list:
    """min(k, distinct images) index arrays of the real files, each a part of their distinct
    images (duplicates together), the distinct images split by a seeded permutation."""
    groups = duplicate_groups(np.asarray(images, np.float32), order="hash")
    distinct = np.random.default_rng([int(seed), 48]).permutation(np.unique(groups))
    return [np.flatnonzero(np.isin(groups, part)) for part in np.array_split(distinct, min(k, len(distinct)))]


def _synthetic_needed(recipes) -> bool:
    return any(recipe.kind in ("synthetic", "pretrained") for recipe in recipes)


def _cross_validated(estimator: str, data: AugmentedSet, recipes: tuple, seed: int, synthetic=None) -> tuple:
    """({recipe: per-image errors of every real file, in `parts` order}, the synthetic-alone
    predictor or None): each recipe trained K times without one part, scored on it. The
    synthetic set alone does not depend on the real files: trained once (or `synthetic` given),
    and the 'pretrained' recipe starts from it."""
    real_images, real_lights = (np.asarray(a) for a in data.real)
    parts = _cross_validation_parts(real_images, seed, folds(estimator))
    if synthetic is None and _synthetic_needed(recipes):
        synthetic = train(estimator, data, SYNTHETIC, seed=seed)
    from g2r_jax.downstream.illuminant.estimators import decoded_for

    real_images = decoded_for(estimator, real_images)    # K x candidates trainings: each image decoded once
    data = AugmentedSet(real=(real_images, real_lights), synthetic=(decoded_for(estimator, data.synthetic[0]),
                                                                    data.synthetic[1]))
    errors = {recipe: [] for recipe in recipes}
    for held in parts:
        kept = np.setdiff1d(np.arange(len(real_images)), held)
        part = dataclasses.replace(data, real=(real_images[kept], real_lights[kept]))
        for recipe in recipes:
            predict = train(estimator, part, recipe, seed=seed, synthetic=synthetic)
            errors[recipe].append(angular_error_degrees(predict(real_images[held]), real_lights[held]))
    return {recipe: np.concatenate(values) for recipe, values in errors.items()}, synthetic


def _choose(estimator: str, data: AugmentedSet, seed: int, recipes, synthetic=None) -> tuple:
    recipes = tuple(dict.fromkeys((REAL,) + tuple(recipes or candidates(estimator))))
    if len(np.unique(duplicate_groups(np.asarray(data.real[0], np.float32)))) < MIN_FILES:
        return FEW_FILES, {}, synthetic
    errors, synthetic = _cross_validated(estimator, data, recipes, seed, synthetic)
    return _clear_winner(errors), {str(r): float(np.mean(e)) for r, e in errors.items()}, synthetic


def choose(estimator: str, data: AugmentedSet, *, seed: int = 0, recipes=None) -> tuple:
    """The recipe whose estimator errs least on the real files in K-fold cross-validation, if it
    beats real alone by more than the files can tell (module docstring).

    **Returns:** (the chosen `Recipe`, {recipe name: cross-validated mean angular error in
    degrees}; empty when there were too few files and `FEW_FILES` was taken)."""
    recipe, scores, _ = _choose(estimator, data, seed, recipes)
    return recipe, scores


def _beats(errors: dict, recipe: Recipe, base: Recipe) -> bool:
    """Whether `recipe` errs less than `base` by more than `MARGIN` standard errors of the paired
    per-image differences."""
    difference = errors[recipe] - errors[base]
    if len(difference) < 2:
        return False
    return float(np.mean(difference)) < -MARGIN * float(np.std(difference, ddof=1) / np.sqrt(len(difference)))


def _clear_winner(errors: dict) -> Recipe:
    """The base is `REAL`, or `SYNTHETIC` when it beats `REAL` clearly (`_beats`); a combination
    replaces the base only when it beats the base clearly too, the lowest mean among those that
    do. Each step away from the simplest recipe is one the files can tell from noise: choosing
    the lowest of several noisy means instead (every candidate that beats `REAL`) picked
    combinations worse than g2r_jax alone on the test folds with ten files
    (docs/pages/validation/augmentation.md)."""
    base = SYNTHETIC if SYNTHETIC in errors and _beats(errors, SYNTHETIC, REAL) else REAL
    clear = [r for r in errors if r not in (REAL, SYNTHETIC) and _beats(errors, r, base)]
    return min(clear, key=lambda r: float(np.mean(errors[r]))) if clear else base


def train_chosen(estimator: str, data: AugmentedSet, *, seed: int = 0, recipes=None, synthetic=None) -> tuple:
    """`choose` the recipe, then train it on all the real files. `synthetic`: the estimator
    already trained on `data.synthetic` with this `seed` (e.g. the synthetic row's own), reused
    as the 'synthetic' candidate and the first network of 'pretrained': the result is the same,
    with fewer trainings. **Returns:** (predictor, recipe, the held-out scores)."""
    recipe, scores, synthetic = _choose(estimator, data, seed, recipes, synthetic)
    return train(estimator, data, recipe, seed=seed, synthetic=synthetic), recipe, scores
