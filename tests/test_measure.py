"""The measurement toolkit (`g2r_jax.measure`): robust spreads, folds, the angular error."""

from __future__ import annotations

import numpy as np
import pytest

from g2r_jax import measure
from g2r_jax.measure import bursts, photon_transfer


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


def test_distinct_groups_give_the_folds_of_no_groups():
    """Files without duplicates (`duplicate_groups` labels 0..n-1) keep the folds drawn without groups."""
    for n, k, seed in ((10, 3, 0), (31, 5, 7), (6, 2, 3)):
        plain = measure.folds_of(n, k, seed)
        grouped = measure.folds_of(n, k, seed, groups=np.arange(n))
        assert all(np.array_equal(a, b) for a, b in zip(plain, grouped))


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


# ---------------------------------------------------------------- bursts and photon transfer


def _gaussian_burst(shot, read, n=8, seed=0, shape=(4, 96, 128)):
    """(n, 4, h, w) normalised frames of a static ramp with variance shot x + read (no rounding)."""
    rng = np.random.default_rng(seed)
    scene = np.broadcast_to(np.linspace(0.0, 0.6, shape[-1]), shape)
    return (scene + np.sqrt(shot * scene + read) * rng.standard_normal((n,) + shape)).astype(np.float32)


def test_bin_moments_are_each_bins_mean_and_standard_error():
    rng = np.random.default_rng(2)
    level, variance = rng.uniform(0, 1, 5000), rng.gamma(3.0, 1.0, 5000)
    edges = np.array([0.0, 0.25, 0.5, 1.0])
    signal, mean, se = photon_transfer.bin_moments(photon_transfer.bin_sums(level, level, variance, edges),
                                                   min_pixels=10, ddof=1)
    for b in range(3):
        chosen = (level >= edges[b]) & (level < edges[b + 1])
        assert signal[b] == pytest.approx(level[chosen].mean())
        assert mean[b] == pytest.approx(variance[chosen].mean())
        assert se[b] == pytest.approx(variance[chosen].std(ddof=1) / np.sqrt(chosen.sum()))
    assert np.isnan(photon_transfer.bin_moments(photon_transfer.bin_sums(level, level, variance, edges),
                                                min_pixels=10_000)[1]).all()


def test_photon_transfer_estimators_recover_the_noise_they_were_given():
    shot, read = 2e-4, 1e-5
    frames = _gaussian_burst(shot, read)
    found_shot, found_read = photon_transfer.regression_shot_read(frames, np.full(4, -1.0))
    np.testing.assert_allclose(found_shot, shot, rtol=0.05)
    np.testing.assert_allclose(found_read, read, rtol=0.1)
    nlf = photon_transfer.temporal_nlf(frames, pedestal=np.zeros(4), clip=np.full(4, 0.98), clip_low=np.full(4, -1.0),
                                       edges=np.linspace(0.0, 0.7, 8))["all"]
    ok = np.isfinite(nlf.variance)
    z = (nlf.variance - (shot * nlf.signal + read)) / nlf.se
    assert ok.sum() >= 20 and np.all(np.abs(z[ok]) < 4.5), z[ok]
    fitted_shot, fitted_read = photon_transfer.fit_shot_read(nlf.signal, nlf.variance, nlf.se)
    np.testing.assert_allclose(fitted_shot, shot, rtol=0.05)


def test_a_moved_or_brighter_frame_is_not_the_burst_s_scene():
    frames = _gaussian_burst(2e-4, 3e-6, n=6, seed=3)
    assert bursts.scene_outliers(frames) == {}
    moved = frames.copy()
    moved[2] = np.roll(moved[2], 5, axis=-1)
    brighter = frames.copy()
    brighter[4] *= 1.08
    assert list(bursts.scene_outliers(moved)) == [2] and "static scene" in bursts.scene_outliers(moved)[2]
    assert list(bursts.scene_outliers(brighter)) == [4]


def test_find_bursts_groups_files_by_thumbnail_up_to_a_gain():
    rng = np.random.default_rng(4)
    scene, other = rng.uniform(0.1, 1.0, (4, 16, 16)), rng.uniform(0.1, 1.0, (4, 16, 16))
    file = lambda thumb, **extra: {"shape": (64, 64), "iso": 100.0, "thumbnail": thumb, **extra}
    files = ([file(scene * g) for g in (1.0, 1.02, 0.97)] + [file(other)] + [file(scene, dark_frame=True)]
             + [file(scene * 1.01), file(scene, iso=800.0)])
    assert bursts.find_bursts(files) == [[0, 1, 2, 5]]


def test_duplicate_groups_by_hash_do_not_depend_on_order():
    from g2r_jax.measure import duplicate_groups

    rng = np.random.default_rng(3)
    arrays = [rng.random((4, 4)) for _ in range(5)]
    arrays += [arrays[1].copy(), arrays[3].copy()]
    labels = duplicate_groups(arrays, order="hash")
    shuffled = duplicate_groups(arrays[::-1], order="hash")[::-1]
    assert np.array_equal(labels, shuffled)
    assert labels[5] == labels[1] and labels[6] == labels[3] and len(set(labels.tolist())) == 5
    assert duplicate_groups([np.zeros((2, 3)), np.zeros((3, 2))]).tolist() == [0, 1]   # same bytes, other shape
    with pytest.raises(ValueError, match="order"):
        duplicate_groups(arrays, order="sorted")
