"""Augmentation: an illuminant estimator trained on a user's labelled real files together with
synthetic RAW (g2r_jax, or UPI for comparison), the recipe chosen on the real files alone (issue 48).

Recipes (`Recipe`):
- `real`: the real files alone (what the user has without synthetic RAW);
- `mixed` w: real and synthetic images pooled, the synthetic ones weighted to a share w of the
  training signal: each real image weighs (1 - w) / n_real, each synthetic one w / n_synthetic (the
  closed forms' least squares: `estimators.train_moments` / `train_histogram` `weights`; the CNN:
  each step's crops draw their images by these weights, its checkpoints judged on real images only);
- `pretrained` (CNN): trained on the synthetic set, then fine-tuned on the real files at a third of
  the learning rate (the usual transfer schedule; Yosinski et al., "How transferable are features
  in deep neural networks?", NeurIPS 2014).

The choice (`choose`): the real training files are split again by a seeded permutation of their
distinct images (duplicates kept together), two thirds to train, one third held out; every
candidate is trained on the two thirds (with all the synthetic images) and scored by its mean
angular error on the held-out third; the lowest wins, `real` on a tie, and is retrained on all
the real training files. `real` is always a candidate, so the combination is worse than real
alone only by what the held-out third cannot tell. With fewer than `MIN_FILES` distinct real files
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


@dataclasses.dataclass(frozen=True)
class Recipe:
    """How real and synthetic images are combined: `kind` 'real', 'mixed' or 'pretrained'; `weight`
    the synthetic share of a 'mixed' set."""

    kind: str
    weight: float = 0.0

    def __str__(self) -> str:
        return f"mixed {self.weight:g}" if self.kind == "mixed" else self.kind


REAL = Recipe("real")
FEW_FILES = Recipe("mixed", 0.5)


@dataclasses.dataclass(frozen=True)
class AugmentedSet:
    """A training set of an augmented row: `real` and `synthetic`, each (images, illuminants)."""

    real: tuple
    synthetic: tuple


def candidates(estimator: str) -> tuple:
    """The recipes tried for `estimator`: real alone and four mixes for the closed forms (cheap;
    up to 0.9: with ten files, g2r_jax RAW alone beat them, the issue's first measurement), a mix
    and pretraining for the CNN (each candidate is a training)."""
    if estimator == "cnn":
        return (REAL, Recipe("mixed", 0.5), Recipe("pretrained"))
    return (REAL,) + tuple(Recipe("mixed", w) for w in (0.25, 0.5, 0.75, 0.9))


def _mixed_weights(n_real: int, n_synthetic: int, weight: float) -> np.ndarray:
    return np.r_[np.full(n_real, (1.0 - weight) / n_real), np.full(n_synthetic, weight / n_synthetic)]


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
    weights = _mixed_weights(len(real_images), len(synthetic_images), recipe.weight)
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
    scores = {}
    for recipe in recipes:
        predict = train(estimator, part, recipe, seed=seed)
        scores[str(recipe)] = float(np.mean(angular_error_degrees(predict(real_images[held]), real_lights[held])))
    best = min(recipes, key=lambda r: (scores[str(r)], r != REAL))
    return best, scores


def train_chosen(estimator: str, data: AugmentedSet, *, seed: int = 0, recipes=None) -> tuple:
    """`choose` the recipe, then train it on all the real files. **Returns:** (predictor, recipe,
    the held-out scores)."""
    recipe, scores = choose(estimator, data, seed=seed, recipes=recipes)
    return train(estimator, data, recipe, seed=seed), recipe, scores
