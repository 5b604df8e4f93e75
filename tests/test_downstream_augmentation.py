"""Augmentation (issue 48): real files + synthetic RAW, the recipe chosen on the training files."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from g2r_jax.downstream.illuminant import augmentation as aug
from g2r_jax.downstream.illuminant import estimators as est
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
    assert scores["mixed, g2r_jax as 300 files"] > scores["real"] + 1    # misleading synthetic files cost, and are seen to


def test_cross_validation_scores_every_real_file_once_with_duplicates_together():
    images = np.random.default_rng(0).uniform(0, 1, (10, 4, 4, 3)).astype(np.float32)
    images = np.concatenate([images, images[:3]])      # three files copied: one scene each
    parts = aug._cross_validation_parts(images, seed=5)
    assert len(parts) == 3 and all(len(p) for p in parts)
    assert np.array_equal(np.sort(np.concatenate(parts)), np.arange(len(images)))
    for copy, original in zip(range(10, 13), range(3)):
        assert [copy in p for p in parts] == [original in p for p in parts]
    again = aug._cross_validation_parts(images, seed=5)
    assert all(np.array_equal(a, b) for a, b in zip(parts, again))
    each = aug._cross_validation_parts(images, seed=5, k=aug.folds("histogram"))   # 10 distinct: one part each
    assert len(each) == 10 and sorted(len(p) for p in each) == [1] * 7 + [2] * 3
    assert aug.folds("cnn") == 3 and aug.folds("moments") == aug.folds("histogram") > 3


def test_synthetic_alone_is_chosen_over_few_real_files_and_trained_once(worlds, monkeypatch):
    real, synthetic, (test_x, test_y), _ = worlds
    few = (real[0][:6], real[1][:6])
    trained = []
    original = est.train_estimator
    monkeypatch.setattr(est, "train_estimator", lambda kind, x, *a, **k: trained.append(len(x)) or original(kind, x, *a, **k))
    predict, recipe, scores = aug.train_chosen("moments", aug.AugmentedSet(few, synthetic), seed=0,
                                               recipes=(aug.REAL, aug.SYNTHETIC))
    assert recipe == aug.SYNTHETIC and scores["g2r_jax alone"] < scores["real"], scores
    assert trained.count(len(synthetic[0])) == 1          # not once per fold, nor again for the final
    alone = aug.train("moments", aug.AugmentedSet(few, synthetic), aug.SYNTHETIC)(test_x)
    np.testing.assert_allclose(predict(test_x), alone, atol=1e-6)


def test_a_combination_must_beat_the_synthetic_set_alone_when_that_beats_real_files_alone():
    noise = np.random.default_rng(1).normal(0, 0.3, 30)
    real, synthetic = 4.0 + noise, 3.0 + noise + 0.05 * np.random.default_rng(2).normal(size=30)
    barely = synthetic - 0.01 + 0.5 * np.random.default_rng(3).normal(size=30)
    clearly = synthetic - 0.5
    mixed, pretrained = aug.Recipe("mixed", 30), aug.Recipe("pretrained")
    assert aug._clear_winner({aug.REAL: real, aug.SYNTHETIC: synthetic, mixed: barely}) == aug.SYNTHETIC
    assert aug._clear_winner({aug.REAL: real, aug.SYNTHETIC: synthetic, mixed: barely, pretrained: clearly}) == pretrained
    assert aug._clear_winner({aug.REAL: real, mixed: barely}) == mixed          # no synthetic candidate: against real
    assert aug._clear_winner({aug.REAL: real, aug.SYNTHETIC: real + 0.01}) == aug.REAL


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


def test_experiment_rows_see_the_labelled_files_of_the_training_folds(monkeypatch):
    """'real' and 'real_plus_fitted' train on the same `labelled` files of the training folds (never
    the test fold), the recipes are kept per fold, and the report's sentence says what adding
    g2r_jax RAW is worth."""
    from test_downstream_content_rows import _cg, _fake_sets, _real_set

    from g2r_jax.downstream.illuminant import experiment, reporting
    from g2r_jax.measure import folds_of

    real, profile = _real_set(count=18)
    index = {image.tobytes(): i for i, image in enumerate(real.images)}
    seen = {"real": [], "real_plus_fitted": []}

    def alone(name, x, y, seed=0, weights=None):
        seen["real"].append({index[i.tobytes()] for i in np.asarray(x)})
        return lambda test: np.tile(np.asarray(y).mean(0), (len(test), 1))

    def chosen(estimator, data, seed=0, recipes=None, synthetic=None):
        seen["real_plus_fitted"].append({index[i.tobytes()] for i in np.asarray(data.real[0])})
        assert len(data.synthetic[0]) == 50
        return (lambda test: np.tile(np.asarray(data.real[1]).mean(0) * 1.01, (len(test), 1))), aug.REAL, {}

    monkeypatch.setattr(est, "train_estimator", alone)
    monkeypatch.setattr(aug, "train_chosen", chosen)
    _fake_sets(monkeypatch, [])
    result = experiment.illuminant_experiment(real, profile, _cg(), rows=("real", "real_plus_fitted"),
                                              estimators=("moments",), seeds=(0, 1), n=50, folds=3,
                                              illuminant_model="prior", labelled=6)
    tests = folds_of(len(real.images), 3, 0, groups=real.groups)
    assert seen["real"] == seen["real_plus_fitted"] and len(seen["real"]) == 6
    for k, files in enumerate(seen["real"]):
        assert len(files) == 6 and not files & set(tests[k % 3].tolist())
    assert result.recipes[("real_plus_fitted", "moments")] == ["real"] * 6 and result.labelled == 6
    phrase = reporting.augmentation_phrase(result, "moments")
    assert phrase.startswith("with 6 labelled files, adding g2r_jax RAW") and "recipe chosen" in phrase
    assert result.to_dict()["recipes"]["real_plus_fitted/moments"] == ["real"] * 6


def test_the_labelled_curve_has_a_point_per_count_and_draws_it(monkeypatch, tmp_path):
    from test_downstream_content_rows import _cg, _fake_sets, _real_set

    from g2r_jax.downstream.illuminant import experiment, labelled_curve

    real, profile = _real_set(count=30)
    sizes = []

    def alone(name, x, y, seed=0, weights=None):
        sizes.append(len(x))
        return lambda test: np.tile(np.asarray(y).mean(0), (len(test), 1))

    def chosen(estimator, data, seed=0, recipes=None, synthetic=None):
        return (lambda test: np.tile(np.asarray(data.synthetic[1]).mean(0), (len(test), 1))), aug.Recipe("mixed", 30), {}

    monkeypatch.setattr(est, "train_estimator", alone)
    monkeypatch.setattr(aug, "train_chosen", chosen)
    _fake_sets(monkeypatch, [])
    common = dict(estimators=("moments",), seeds=(0,), n=50, folds=3)
    full = experiment.illuminant_experiment(real, profile, _cg(), rows=("fitted", "real", "real_plus_fitted"),
                                            illuminant_model="prior", **common)
    sizes.clear()
    curve = labelled_curve.run_curve(real, profile, _cg(), full, counts=(5, 10, 25, 400), **common)
    assert list(curve.points["moments"]) == ["5", "10", "all"]         # 25 and 400: not below the 20 training files
    assert sorted(set(sizes)) == [5, 10]
    for point in curve.points["moments"].values():
        assert set(point) == {"real", "real_plus_fitted"} and point["real"]["seed_min"] <= point["real"]["mean"]
    assert curve.alone["moments"] == full.summary("fitted", "moments")["mean"]
    table = curve.table()
    assert "| moments | 5 |" in table and "| moments | all |" in table
    assert curve.figure(tmp_path / "augmentation.png") and (tmp_path / "augmentation.png").stat().st_size > 1000
    with pytest.raises(ValueError, match="real_plus_fitted"):
        labelled_curve.run_curve(real, profile, _cg(), dataclasses.replace(full, rows=("fitted", "real")),
                                 counts=(5,), **common)


def test_a_bad_curve_option_is_refused_before_any_work(tmp_path, capsys):
    from g2r_jax.cli import downstream

    folder = tmp_path / "dngs"
    folder.mkdir()
    status = downstream.main(["--measured", str(folder), "--cg", str(folder), "--report", str(tmp_path / "r"),
                              "--curve", "10,ten"])
    assert status == 2 and "--curve 10,ten" in capsys.readouterr().err


@pytest.mark.slow
def test_a_given_synthetic_network_is_the_pretraining_and_changes_nothing(worlds, monkeypatch):
    """`train(..., synthetic=)`: the 'synthetic' recipe's network reused as the first network of
    'pretrained' gives the very estimates of a pretraining from scratch (same set, seed, config)."""
    real, synthetic, (test_x, _), _ = worlds
    small = dataclasses.replace(est.CnnConfig(), checkpoints=2, steps_per_checkpoint=20)
    monkeypatch.setattr(est, "CnnConfig", lambda: small)
    monkeypatch.setattr(est, "train_cnn", lambda *a, **k: _train_small(small, *a, **k))
    monkeypatch.setitem(est._TRAINERS, "cnn", est.train_cnn)
    data = aug.AugmentedSet(real, synthetic)
    first = aug.train("cnn", data, aug.SYNTHETIC, seed=4)
    again = aug.train("cnn", data, aug.Recipe("pretrained"), seed=4)(test_x)
    reused = aug.train("cnn", data, aug.Recipe("pretrained"), seed=4, synthetic=first)(test_x)
    np.testing.assert_array_equal(again, reused)
    assert aug.train("cnn", data, aug.SYNTHETIC, seed=4, synthetic=first) is first


def _train_small(small, *args, config=None, **kwargs):
    return _ORIGINAL_TRAIN_CNN(*args, config=config or small, **kwargs)


_ORIGINAL_TRAIN_CNN = est.train_cnn


def test_the_augmented_row_reuses_its_synthetic_rows_set_and_estimator(monkeypatch, tmp_path):
    """With 'fitted' and 'real_plus_fitted' in one experiment, each fold builds the g2r_jax set once
    and trains the estimator on it once (the augmented row's 'synthetic' candidate is that
    estimator), and the errors are those of the rows run apart."""
    from test_downstream_content_rows import _cg, _fake_sets, _real_set

    from g2r_jax.downstream.illuminant import experiment

    real, profile = _real_set(count=18)
    calls, trained = [], []
    original = est.train_estimator

    def counting(kind, images, lights, *, seed=0, weights=None):
        trained.append((kind, len(images), weights is None))
        return original(kind, images, lights, seed=seed, weights=weights)

    monkeypatch.setattr(est, "train_estimator", counting)
    _fake_sets(monkeypatch, calls)
    run = lambda rows: experiment.illuminant_experiment(real, profile, _cg(), rows=rows, estimators=("histogram",),
                                                        seeds=(0,), n=50, folds=3, illuminant_model="prior")
    together = run(("fitted", "real_plus_fitted"))
    g2r_sets = len([c for c in calls if c[0] == "g2r"])
    synthetic_alone = len([t for t in trained if t[1] == 50 and t[2]])
    assert g2r_sets == 3 and synthetic_alone == 3          # once per fold, for both rows
    apart = [run((row,)) for row in ("fitted", "real_plus_fitted")]
    for row, result in zip(("fitted", "real_plus_fitted"), apart):
        np.testing.assert_array_equal(together.errors[(row, "histogram")][0], result.errors[(row, "histogram")][0])
    assert together.recipes == {**apart[1].recipes}
    scores = together.choice_scores[("real_plus_fitted", "histogram")]
    assert len(scores) == 3 and all(set(s) == {str(r) for r in aug.candidates("histogram")} for s in scores)
    assert together.to_dict()["choice_scores"]["real_plus_fitted/histogram"] == scores

    from g2r_jax.downstream.base.cache import DownstreamCache

    store = DownstreamCache(tmp_path / "store")
    first = experiment.illuminant_experiment(real, profile, _cg(), rows=("fitted", "real_plus_fitted"),
                                             estimators=("histogram",), seeds=(0,), n=50, folds=3,
                                             illuminant_model="prior", cache=store)
    stored = experiment.illuminant_experiment(real, profile, _cg(), rows=("fitted", "real_plus_fitted"),
                                              estimators=("histogram",), seeds=(0,), n=50, folds=3,
                                              illuminant_model="prior", cache=DownstreamCache(tmp_path / "store"))
    assert stored.choice_scores == first.choice_scores == together.choice_scores


def test_the_histogram_reads_decoded_pixels_to_the_same_bit(worlds):
    """`ChromaPixels`: the histogram's features, training and predictions from a set's pixels
    decoded once equal those from its images, bit for bit, sliced and concatenated alike."""
    (x, y), (sx, sy), (test_x, _), _ = worlds
    pixels, synthetic = est.chroma_pixels(x), est.chroma_pixels(sx)
    grid = est.HistogramGrid(centre=(0.3, -0.2))
    np.testing.assert_array_equal(est.histogram_features(x, grid), est.histogram_features(pixels, grid))
    both = np.concatenate([x[2:9], sx])
    joined = est.ChromaPixels.concatenate([pixels[2:9], synthetic])
    weights = np.r_[np.ones(7), np.full(len(sx), 0.1)]
    lights = np.concatenate([y[2:9], sy])
    from_images = est.train_histogram(both, lights, weights=weights)
    from_pixels = est.train_histogram(joined, lights, weights=weights)
    np.testing.assert_array_equal(from_images(test_x), from_pixels(test_x))
    np.testing.assert_array_equal(from_images(test_x), from_images(est.chroma_pixels(test_x)))
    with pytest.raises(ValueError, match="negative"):
        est.chroma_pixels(-x)
    with pytest.raises(TypeError, match="not an image array"):
        np.asarray(pixels)


def test_the_histogram_recipe_choice_is_that_of_its_images(worlds, monkeypatch):
    """The cross-validation on decoded pixels scores every recipe exactly as on the images."""
    real, synthetic, _, _ = worlds
    data = aug.AugmentedSet(real, synthetic)
    recipe, scores = aug.choose("histogram", data, seed=3)
    monkeypatch.setattr(est, "chroma_pixels", lambda images: np.asarray(images, np.float32))
    again, plain = aug.choose("histogram", data, seed=3)
    assert recipe == again and scores == plain
