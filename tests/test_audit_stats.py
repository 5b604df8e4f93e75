"""Unit checks of the audit's statistics and tests on inputs with known answers."""

from __future__ import annotations

import numpy as np

from g2r_jax.audit import significance, stats


def test_robust_variance_is_unbiased_for_gaussian_and_robust_to_edges():
    rng = np.random.default_rng(0)
    d = rng.normal(0, 0.02, 200_000)
    assert abs(stats._robust_variance(d) / 0.02**2 - 1) < 0.02
    d[:5000] += 1.0  # 2.5% of differences straddle an edge
    assert abs(stats._robust_variance(d) / 0.02**2 - 1) < 0.1


def test_banding_estimator_recovers_row_offsets():
    rng = np.random.default_rng(1)
    planes = 0.3 + rng.normal(0, 0.01, (4, 100, 150))
    rows = rng.normal(0, 0.003, 200)            # full-mosaic rows
    planes[0] += rows[0::2, None]
    planes[1] += rows[0::2, None]
    planes[2] += rows[1::2, None]
    planes[3] += rows[1::2, None]
    row_var, col_var = stats.banding(planes)
    assert abs(np.sqrt(row_var) / 0.003 - 1) < 0.25
    assert abs(col_var) < 0.1 * 0.003**2


def test_clipping_level_finds_the_spike():
    rng = np.random.default_rng(2)
    planes = np.clip(rng.uniform(0, 1.2, (4, 100, 150)), None, 0.93)
    span = np.full(4, 3839.0)
    planes = np.round(planes * span[:, None, None]) / span[:, None, None]
    assert np.allclose(stats.clipping_level(planes, 4095, span), 0.93, atol=1e-3)
    assert np.all(np.isnan(stats.clipping_level(planes * 0.5, 4095, span)))


def test_max_t_permutation_calibrated_under_null_and_powerful_under_shift():
    rng = np.random.default_rng(3)
    ps = [significance.max_t_permutation(rng.normal(size=(24, 4)), rng.normal(size=(24, 4)),
                                         n_permutations=200, seed=i)["p"] for i in range(60)]
    assert 0.02 < np.mean(np.asarray(ps) < 0.1) < 0.25
    shifted = significance.max_t_permutation(rng.normal(size=(24, 4)) + [1.5, 0, 0, 0], rng.normal(size=(24, 4)))
    assert shifted["p"] < 0.001


def test_energy_test_matches_the_energy_distance():
    from g2r_jax.illuminants import energy_distance

    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(20, 2)), rng.normal(size=(100, 2)) + [2.0, 0]
    test = significance.energy_permutation(a, b, n_permutations=500)
    assert abs(test["energy"] - energy_distance(a, b)) < 1e-9
    assert test["p"] < 0.01


def test_consistent_outliers_needs_many_files():
    shape = (20, 30)
    hot = (np.array([3]), np.array([5]), np.array([1.0]))
    noise = (np.array([7]), np.array([9]), np.array([0.8]))
    found = significance.consistent_outliers([hot] * 6 + [noise], shape)
    assert found["count"] == 1 and found["rows"][0] == 3 and found["cols"][0] == 5
    assert found["p"] < 1e-3 and found["expected"] < 1e-3
