"""The measurement toolkit (`g2r_jax.measure`): robust spreads, folds, the angular error."""

from __future__ import annotations

import numpy as np
import pytest

from g2r_jax import measure


# ---------------------------------------------------------------- robust spreads


def test_robust_spreads_recover_a_gaussian_sd_despite_outliers():
    rng = np.random.default_rng(0)
    values = rng.normal(5.0, 2.0, 200_000)
    values[:1000] = 1e6                                  # 0.5 % hot pixels
    assert measure.mad_sd(values) == pytest.approx(2.0, rel=0.01)
    assert measure.iqr_sd(values) == pytest.approx(2.0, rel=0.01)
    assert measure.robust_sd(values) == pytest.approx(2.0, rel=0.01)
    assert np.sqrt(measure.trimmed_variance(rng.normal(0.0, 2.0, 200_000))) == pytest.approx(2.0, rel=0.01)
    assert np.std(values) > 100                          # what the outliers do to a plain sd


def test_robust_sd_floor_and_degenerate_sets():
    constant = np.full(50, 3.0)
    assert measure.mad_sd(constant) == 0.0
    assert np.isnan(measure.robust_sd(constant))                      # no spread, no floor: no unit
    assert measure.robust_sd(constant, resolution=0.02) == 0.02       # the statistic's resolution
    assert measure.robust_sd([1.0, 2.0, 3.0, 100.0], resolution=0.02) == pytest.approx(1.482602)
    assert np.isnan(measure.robust_sd([1.0, np.nan, np.inf]))          # one finite value
    assert np.isnan(measure.mad_sd([])) and np.isnan(measure.iqr_sd([]))


# ---------------------------------------------------------------- folds


def test_folds_partition_and_keep_earlier_releases_folds():
    folds = measure.folds_of(10, 3, seed=4)
    assert sorted(np.concatenate(folds).tolist()) == list(range(10))
    order = np.random.default_rng(4).permutation(10)                 # the folds audit.gain and downstream drew
    assert all(np.array_equal(f, np.sort(order[i::3])) for i, f in enumerate(folds))
    assert [len(f) for f in folds] == [4, 3, 3]
    assert not all(np.array_equal(a, b) for a, b in zip(folds, measure.folds_of(10, 3, seed=5)))


@pytest.mark.parametrize("seed", range(5))
def test_folds_with_groups_never_split_a_group(seed):
    rng = np.random.default_rng(seed)
    groups = rng.integers(0, 7, 40)
    folds = measure.folds_of(40, 3, seed, groups=groups)
    assert sorted(np.concatenate(folds).tolist()) == list(range(40))
    fold_of = np.empty(40, int)
    for k, held in enumerate(folds):
        fold_of[held] = k
    for label in np.unique(groups):
        assert len(set(fold_of[groups == label])) == 1
    with pytest.raises(ValueError, match="distinct"):
        measure.folds_of(4, 3, seed, groups=[0, 0, 1, 1])


def test_duplicate_groups_follow_the_pixels_not_the_name():
    a = np.arange(12, dtype=np.uint16).reshape(3, 4)
    labels = measure.duplicate_groups([a, a.copy(), a + 1, a.astype(np.float32), a])
    assert labels.tolist() == [0, 0, 1, 2, 0]


# ---------------------------------------------------------------- angular error


def test_angular_error_matches_arccos_and_is_scale_free():
    rng = np.random.default_rng(1)
    e, t = rng.uniform(0.05, 1.0, (500, 3)), rng.uniform(0.05, 1.0, (500, 3))
    cosine = np.sum(e * t, 1) / (np.linalg.norm(e, axis=1) * np.linalg.norm(t, axis=1))
    np.testing.assert_allclose(measure.angular_error_degrees(e, t), np.degrees(np.arccos(cosine)), atol=1e-6)
    np.testing.assert_allclose(measure.angular_error_degrees(3.0 * e, t), measure.angular_error_degrees(e, t))


def test_angular_error_of_chart_patches_keeps_their_shape_and_nan_marks_missing_ones():
    patches = np.ones((2, 24, 3))
    patches[1, 5] = np.nan
    patches[0, 7] = 0.0
    tilted = patches * np.array([1.0, 1.0, 1.1])
    errors = measure.angular_error_degrees(tilted, patches, invalid="nan")
    assert errors.shape == (2, 24)
    assert np.isnan(errors[1, 5]) and np.isnan(errors[0, 7]) and np.isfinite(errors).sum() == 46
    with pytest.raises(ValueError, match="not finite"):
        measure.angular_error_degrees(tilted, patches)
    with pytest.raises(ValueError, match="invalid"):
        measure.angular_error_degrees(tilted, patches, invalid="skip")


def test_error_summary_best_and_worst_quarters():
    summary = measure.error_summary(np.arange(1.0, 9.0))
    assert summary == {"mean": 4.5, "median": 4.5, "best25": 1.5, "worst25": 7.5}
