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


def test_a_component_seen_in_few_files_does_not_swamp_the_max_t_null():
    """The mixed-size night set whose early clipping was missed: red clips in 3 measured and 2
    simulated files (repeated values, floor-sized SE), the greens in all 24 + 24 and 3.6 % low."""
    rng = np.random.default_rng(5)
    measured = np.full((24, 3), np.nan)
    simulated = np.full((24, 3), np.nan)
    measured[:, 1:] = 0.964 + 0.002 * rng.normal(size=(24, 2))
    simulated[:, 1:] = 1.0
    measured[:3, 0], simulated[:2, 0] = 0.964, 1.0
    result = significance.max_t_permutation(measured, simulated, floor=3e-4, n_permutations=2000)
    assert result["p"] < 0.001, result
    assert abs(result["t"][0]) > 50          # red is still reported, outside the tested family
    alone = significance.max_t_permutation(measured[:, :1], simulated[:, :1], floor=3e-4, n_permutations=2000)
    assert alone["p"] == 1.0 and alone["score"] == 0.0                  # too few files: not tested at all


def test_energy_test_matches_the_energy_distance():
    from g2r_jax.illuminants.distributions import energy_distance

    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(20, 2)), rng.normal(size=(100, 2)) + [2.0, 0]
    test = significance.energy_permutation(a, b, n_permutations=500)
    assert abs(test["energy"] - energy_distance(a, b)) < 1e-9
    assert test["p"] < 0.01


def test_outliers_skip_plane_borders_and_find_interior_impulses():
    rng = np.random.default_rng(2)
    planes = (0.3 + 0.002 * rng.normal(size=(4, 40, 60))).astype(np.float32)
    planes[1, 10, 20] = 0.9              # interior: mosaic row 2 * 10, col 2 * 20 + 1
    planes[2, 0, 30] = planes[3, 39, 5] = planes[0, 17, 59] = 0.9   # plane borders
    rows, cols, values = stats.outliers(planes, np.ones(4))
    assert list(zip(rows.tolist(), cols.tolist())) == [(20, 41)] and np.allclose(values, 0.9)


def test_consistent_outliers_needs_many_files():
    shape = (20, 30)
    hot = (np.array([3]), np.array([5]), np.array([1.0]))
    noise = (np.array([7]), np.array([9]), np.array([0.8]))
    found = significance.consistent_outliers([hot] * 6 + [noise], shape)
    assert found["count"] == 1 and found["rows"][0] == 3 and found["cols"][0] == 5
    assert found["p"] < 1e-3 and found["expected"] < 1e-3


def test_noise_correlation_is_blind_to_smooth_shading_and_sees_correlated_noise():
    """White noise on a shaded scene reads as white (the README tour's clean file once read as
    correlated noise: first differences keep the shading's slope); noise smoothed along rows does not."""
    from g2r_jax.audit.stats import noise_correlation

    rng = np.random.default_rng(0)
    rows, cols = np.mgrid[0:240, 0:320] / 320.0
    shading = 0.1 + 0.4 * (rows * cols + 0.5 * cols**2)           # smooth, steepest ~0.0025 per pixel
    white = shading[None] + 0.002 * rng.standard_normal((4, 240, 320))
    assert abs(float(noise_correlation(white.astype(np.float32))[0])) < 0.03
    noise = 0.002 * rng.standard_normal((4, 240, 322))
    smoothed = shading[None] + (noise[..., :-2] + noise[..., 1:-1] + noise[..., 2:]) / np.sqrt(3)
    assert float(noise_correlation(smoothed.astype(np.float32))[0]) > 0.5
