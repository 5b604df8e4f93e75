"""Augmentation (issue 48): real files + synthetic RAW, the recipe chosen on the training files."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from g2r_jax.downstream import augmentation as aug
from g2r_jax.downstream import estimators as est
from g2r_jax.measure import angular_error_degrees
from test_downstream_estimators import synthetic_scenes


@pytest.fixture(scope="module")
def worlds():
    """Few real files, many synthetic ones of the same world, a test set, and synthetic files whose
    labels have red and blue swapped (synthetic RAW that teaches the wrong lights)."""
    real = synthetic_scenes(12, seed=11)
    synthetic = synthetic_scenes(300, seed=12)
    test = synthetic_scenes(80, seed=13)
    wrong = (synthetic[0], synthetic[1][:, ::-1])
    return real, synthetic, test, wrong


@pytest.mark.parametrize("kind", ["moments", "histogram"])
def test_zero_weights_leave_images_out_of_the_closed_forms(kind, worlds):
    (x, y), _, (test_x, _), _ = worlds
    weights = np.r_[np.ones(8), np.zeros(4)]
    weighted = est.train_estimator(kind, x, y, weights=weights)(test_x)
    first = est.train_estimator(kind, x[:8], y[:8])(test_x)
    np.testing.assert_allclose(weighted, first, atol=1e-5)


@pytest.mark.parametrize("kind", ["moments", "histogram"])
def test_synthetic_files_help_few_real_files_and_useless_ones_are_refused(kind, worlds):
    real, synthetic, (test_x, test_y), shuffled = worlds
    alone = angular_error_degrees(aug.train(kind, aug.AugmentedSet(real, synthetic), aug.REAL)(test_x), test_y).mean()

    predict, recipe, scores = aug.train_chosen(kind, aug.AugmentedSet(real, synthetic), seed=0)
    helped = angular_error_degrees(predict(test_x), test_y).mean()
    assert recipe.kind == "mixed" and set(scores) == {str(r) for r in aug.candidates(kind)}
    assert scores[str(recipe)] == min(scores.values())
    assert helped < 0.8 * alone, (helped, alone)

    recipe, scores = aug.choose(kind, aug.AugmentedSet(real, shuffled), seed=0)
    assert scores[str(recipe)] <= scores["real"]
    assert scores["mixed 0.75"] > scores["real"] + 1      # the misleading synthetic files cost, and are seen to


def test_too_few_real_files_take_the_stated_recipe(worlds):
    real, synthetic, _, _ = worlds
    few = (real[0][:4], real[1][:4])
    recipe, scores = aug.choose("moments", aug.AugmentedSet(few, synthetic))
    assert recipe == aug.FEW_FILES and scores == {}


def test_unknown_recipes_are_refused(worlds):
    real, synthetic, _, _ = worlds
    with pytest.raises(ValueError, match="unknown recipe"):
        aug.train("moments", aug.AugmentedSet(real, synthetic), aug.Recipe("blend"))
    with pytest.raises(ValueError, match="for the CNN"):
        aug.train("moments", aug.AugmentedSet(real, synthetic), aug.Recipe("pretrained"))


@pytest.mark.slow
def test_cnn_recipes_train_and_fine_tuning_starts_from_the_pretrained_network(worlds, monkeypatch):
    real, synthetic, (test_x, test_y), _ = worlds
    small = dataclasses.replace(est.CnnConfig(), checkpoints=2, steps_per_checkpoint=20)
    monkeypatch.setattr(est, "CnnConfig", lambda: small)
    starts = []
    original = est.train_cnn

    def recording(*args, **kwargs):
        starts.append(kwargs.get("init"))
        return original(*args, **{**kwargs, "config": kwargs.get("config", small)})

    monkeypatch.setattr(est, "train_cnn", recording)
    data = aug.AugmentedSet(real, synthetic)
    for recipe in aug.candidates("cnn"):
        estimates = aug.train("cnn", data, recipe, seed=1)(test_x)
        assert np.all(np.isfinite(estimates)) and estimates.shape == (80, 3)
    assert starts[-2] is None and starts[-1] is not None       # pretrained: then fine-tuned from it
    mixed = est.train_cnn(np.concatenate([real[0], synthetic[0]]), np.concatenate([real[1], synthetic[1]]), seed=1,
                          config=small, sampling=np.r_[np.zeros(12), np.ones(300)],
                          validation_from=np.r_[np.ones(12, bool), np.zeros(300, bool)])
    assert np.isfinite(mixed.validation_error)
