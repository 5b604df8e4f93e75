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
  in deep neural networks?", NeurIPS 2014).

The choice (`choose`): the real training files are split again by a seeded permutation of their
distinct images (duplicates kept together), two thirds to train, one third held out; every
candidate is trained on the two thirds (with all the synthetic images) and scored by its mean
angular error on the held-out third. A candidate replaces `real` only when it beats it by more
than one standard error of the paired per-image differences on the held-out files (`MARGIN`: a
gain the held-out third can tell from noise); among those, the lowest mean wins; the winner is
retrained on all the real training files. So the combination is worse than real alone only by
what the held-out third cannot tell. With fewer than `MIN_FILES` distinct real files
no third can be held out: the recipe is then `FEW_FILES` (stated in the result, not chosen).
The test fold of the experiment is never seen.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from g2r_jax.measure import angular_error_degrees, duplicate_groups

__all__ = ["Recipe", "AugmentedSet", "candidates", "train", "choose", "train_chosen", "MIN_FILES", "FEW_FILES"]

FINE_TUNE_RATE = 1 / 3     # the fine-tuning learning rate, a share of the estimator's own
HELD_OUT = 1 / 3           # share of the real training files held out to choose the recipe
MIN_FILES = 6              # distinct real files needed to hold out a third (at least two)
MARGIN = 1.0               # standard errors of the paired differences a recipe must beat real alone by


@dataclasses.dataclass(frozen=True)
class Recipe:
    """How real and synthetic images are combined: `kind` 'real', 'mixed' or 'pretrained'; `worth`
    the number of real files the synthetic set counts as in a 'mixed' set."""

    kind: str
    worth: float = 0.0

    def __str__(self) -> str:
        return f"mixed, g2r_jax as {self.worth:g} files" if self.kind == "mixed" else self.kind


REAL = Recipe("real")
FEW_FILES = Recipe("mixed", 30)    # the first measurement: g2r_jax alone was worth about 30 labelled files


@dataclasses.dataclass(frozen=True)
class AugmentedSet:
    """A training set of an augmented row: `real` and `synthetic`, each (images, illuminants)."""

    real: tuple
    synthetic: tuple


def candidates(estimator: str) -> tuple:
    """The recipes tried for `estimator`: real alone and the synthetic set worth 10, 30, 100 or 300
    files for the closed forms (cheap; about 30 was g2r_jax alone's worth in the issue's first
    measurement), worth 30 and pretraining for the CNN (each candidate is a training)."""
    if estimator == "cnn":
        return (REAL, Recipe("mixed", 30), Recipe("pretrained"))
    return (REAL,) + tuple(Recipe("mixed", k) for k in (10, 30, 100, 300))


def _mixed_weights(n_real: int, n_synthetic: int, worth: float) -> np.ndarray:
    return np.r_[np.ones(n_real), np.full(n_synthetic, worth / n_synthetic)]


def train(estimator: str, data: AugmentedSet, recipe: Recipe, *, seed: int = 0):
    """One estimator trained by `recipe` on `data`. **Returns:** a predictor (images -> lights)."""
    from g2r_jax.downstream import estimators

    real_images, real_lights = data.real
    if recipe.kind == "real":
        return estimators.train_estimator(estimator, real_images, real_lights, seed=seed)
    synthetic_images, synthetic_lights = data.synthetic
    if recipe.kind == "pretrained":
        if estimator != "cnn":
            raise ValueError(f"recipe 'pretrained' is for the CNN, not {estimator!r}")
        config = estimators.CnnConfig()
        first = estimators.train_cnn(synthetic_images, synthetic_lights, seed=seed, config=config)
        tuned = dataclasses.replace(config, learning_rate=config.learning_rate * FINE_TUNE_RATE)
        return estimators.train_cnn(real_images, real_lights, seed=seed, config=tuned, init=first.params)
    if recipe.kind != "mixed":
        raise ValueError(f"unknown recipe {recipe.kind!r}; expected real, mixed or pretrained")
    images = np.concatenate([np.asarray(real_images, np.float32), np.asarray(synthetic_images, np.float32)])
    lights = np.concatenate([np.asarray(real_lights, np.float64), np.asarray(synthetic_lights, np.float64)])
    weights = _mixed_weights(len(real_images), len(synthetic_images), recipe.worth)
    if estimator == "cnn":
        is_real = np.r_[np.ones(len(real_images), bool), np.zeros(len(synthetic_images), bool)]
        return estimators.train_cnn(images, lights, seed=seed, sampling=weights, validation_from=is_real)
    return estimators.train_estimator(estimator, images, lights, seed=seed, weights=weights)


def _inner_split(images: np.ndarray, seed: int):
    """(inner training, held-out) indices of the real files: a third of their distinct images."""
    groups = duplicate_groups(np.asarray(images, np.float32), order="hash")
    distinct = np.random.default_rng([int(seed), 48]).permutation(np.unique(groups))
    held = distinct[: max(1, int(round(HELD_OUT * len(distinct))))]
    is_held = np.isin(groups, held)
    return np.flatnonzero(~is_held), np.flatnonzero(is_held)


def choose(estimator: str, data: AugmentedSet, *, seed: int = 0, recipes=None) -> tuple:
    """The recipe whose estimator, trained on two thirds of the real files (and the synthetic
    images), errs least on the held-out third (module docstring).

    **Returns:** (the chosen `Recipe`, {recipe name: held-out mean angular error in degrees};
    empty when there were too few files and `FEW_FILES` was taken)."""
    real_images, real_lights = (np.asarray(a) for a in data.real)
    recipes = tuple(recipes or candidates(estimator))
    if len(np.unique(duplicate_groups(real_images.astype(np.float32)))) < MIN_FILES:
        return FEW_FILES, {}
    inner, held = _inner_split(real_images, seed)
    part = dataclasses.replace(data, real=(real_images[inner], real_lights[inner]))
    errors = {}
    for recipe in dict.fromkeys((REAL,) + recipes):
        predict = train(estimator, part, recipe, seed=seed)
        errors[recipe] = angular_error_degrees(predict(real_images[held]), real_lights[held])
    scores = {str(r): float(np.mean(e)) for r, e in errors.items()}
    return _clear_winner(errors), scores


def _clear_winner(errors: dict) -> Recipe:
    """The recipe of lowest mean held-out error among those that beat `REAL` by more than `MARGIN`
    standard errors of the paired differences; `REAL` when none does."""
    base = errors[REAL]
    clear = []
    for recipe, values in errors.items():
        difference = values - base
        if recipe == REAL or len(difference) < 2:
            continue
        standard_error = float(np.std(difference, ddof=1) / np.sqrt(len(difference)))
        if np.mean(difference) < -MARGIN * standard_error:
            clear.append(recipe)
    return min(clear, key=lambda r: float(np.mean(errors[r]))) if clear else REAL


def train_chosen(estimator: str, data: AugmentedSet, *, seed: int = 0, recipes=None) -> tuple:
    """`choose` the recipe, then train it on all the real files. **Returns:** (predictor, recipe,
    the held-out scores)."""
    recipe, scores = choose(estimator, data, seed=seed, recipes=recipes)
    return train(estimator, data, recipe, seed=seed), recipe, scores
