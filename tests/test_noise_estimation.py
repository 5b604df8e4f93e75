"""The per-file noise estimator recovers noise injected by our own simulation, on textured scenes."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from scipy.signal import correlate2d

from g2r_jax.sensor.noise import estimation as ne
from g2r_jax.audit import scenes, synthetic
from g2r_jax.sensor.noise.estimation import to_normalised_planes
from g2r_jax.pipeline import unprocess


def _simulated_planes(seed=3, height=512, width=768, iso=400.0):
    """Dead-leaves scene through `unprocess` (demo camera, noise on, no other effects)."""
    profile = synthetic.demo_profile()
    image = scenes.dead_leaves(seed, height, width, n_leaves=120, r_min=24.0)
    mosaic, meta = unprocess(jax.random.PRNGKey(seed), image, profile, neutral=[0.6, 1.0, 0.7],
                             iso=iso, exposure_gain=1.0, effects=False)
    black, white = np.asarray(profile.black_level, np.float64), float(profile.white_level)
    planes = to_normalised_planes(np.asarray(mosaic), black, white)
    shot, read = np.asarray(meta["noise_shot"], np.float64), np.asarray(meta["noise_read"], np.float64)
    truth = lambda x: shot[:, None] * x + read[:, None] + ne.quantisation_variance(black, white)[:, None]
    return planes, truth, -black / (white - black)


def test_level_function_recovers_injected_noise_on_textured_scene():
    planes, truth, clip_low = _simulated_planes()
    estimate = ne.estimate_noise_level_function(planes, clip_low=clip_low, n_bins=10)
    ok = estimate.valid() & (estimate.counts >= 50)
    assert ok.sum() >= 12, estimate.counts
    true = truth(np.where(ok, estimate.signal, 0.0))
    ratio = estimate.variance[ok] / true[ok]
    inside = (estimate.lower[ok] <= true[ok]) & (true[ok] <= estimate.upper[ok])
    assert np.all(np.abs(ratio - 1) < 0.06), ratio
    # Nominal 95 % intervals cover the truth in 62-93 % of bins over seeds 3-8 with either noise
    # stream (14 bins a seed; measured when the stream changed to the hashed one): they
    # under-cover, an open point of the estimator; this bound only says they are not meaningless.
    assert inside.mean() >= 0.6, (ratio, estimate.lower[ok] / true[ok], estimate.upper[ok] / true[ok])
    # many blocks of a dead-leaves scene straddle an edge: the estimator must have rejected them
    assert estimate.rejected.sum() > 0.2 * (estimate.rejected.sum() + estimate.counts.sum())


def test_level_function_is_not_fooled_by_edges():
    """The same bins averaged without the texture rejection read far more than the noise."""
    planes, truth, clip_low = _simulated_planes(seed=4)
    estimate = ne.estimate_noise_level_function(planes, clip_low=clip_low, n_bins=10, n_bootstrap=20)
    ok = estimate.valid() & (estimate.counts >= 50)
    assert ok.sum() >= 8
    naive = np.full(estimate.variance.shape, np.nan)
    for p, (mean, stats, index) in enumerate(ne._bin_blocks(planes, block=ne.BLOCK, edges=estimate.edges,
                                                            clip=np.ones(4), clip_low=np.resize(clip_low, 4),
                                                            region=None)):
        for b in np.flatnonzero(ok[p]):
            naive[p, b] = ne._solve(stats[index == b, :-1].mean(axis=0), ne.BLOCK)[0]
    true = truth(np.where(ok, estimate.signal, 0.0))[ok]
    assert np.max(naive[ok] / true) > 1.5
    width = estimate.upper[ok] - estimate.lower[ok]   # every bin within its interval widened to ~3 SE
    assert np.all((estimate.lower[ok] - width / 2 <= true) & (true <= estimate.upper[ok] + width / 2)
                  | (np.abs(estimate.variance[ok] / true - 1) < 0.08))   # 0.063 in one bin with the hashed noise stream


def _correlated_planes(kernel, seed=0, height=300, width=480):
    """Planes of piecewise-constant stripes plus noise shot * x + read correlated by `kernel`."""
    rng = np.random.default_rng(seed)
    levels = np.repeat(np.geomspace(0.01, 0.7, 8), width // 8)[None, :].repeat(height, 0)
    shot, read = 3e-4, 2e-6
    planes = []
    k = np.asarray(kernel, np.float64) / np.sqrt(np.sum(np.square(kernel)))
    for _ in range(4):
        white = rng.standard_normal((height + 2, width + 2))
        field = sum(k[i, j] * white[i:i + height, j:j + width] for i in range(3) for j in range(3))
        planes.append(levels + np.sqrt(shot * levels + read) * field)
    return np.stack(planes), lambda x: shot * x + read


@pytest.mark.parametrize("kernel", [np.pad([[1.0]], 1), [[0, 0.25, 0], [0.25, 1, 0.25], [0, 0.25, 0]]])
def test_variance_and_correlation_with_correlated_noise(kernel):
    planes, truth = _correlated_planes(kernel)
    estimate = ne.estimate_noise_level_function(planes, n_bins=10)
    ok = estimate.valid()
    ratio = estimate.variance[ok] / truth(estimate.signal[ok])
    assert abs(np.median(ratio) - 1) < 0.02 and np.all(np.abs(ratio - 1) < 0.08), ratio
    correlation = ne.estimate_noise_correlation(planes, n_bins=10)
    k = np.asarray(kernel, np.float64)
    auto = correlate2d(k, k) / np.sum(k * k)                      # centre (2, 2) = lag 0
    expected = np.array([auto[2, 3], auto[3, 2], auto[3, 3]])     # lags (0,1), (1,0), (1,1)
    assert np.all(np.abs(correlation.neighbour - expected) < 0.03), (correlation.neighbour, expected)
    covered = (correlation.neighbour_lower - 0.01 <= expected) & (expected <= correlation.neighbour_upper + 0.01)
    assert covered.mean() >= 0.75
    assert correlation.white.all() == (expected.max() == 0)


def test_regions_split_the_blocks():
    planes, _, clip_low = _simulated_planes()
    first, second = ne.checkerboard_regions(planes.shape[1:], tile=64)
    assert not np.any(first & second) and np.all(first | second)
    a = ne.estimate_noise_level_function(planes, clip_low=clip_low, region=first, n_bootstrap=10)
    b = ne.estimate_noise_level_function(planes, clip_low=clip_low, region=second, n_bootstrap=10)
    whole = ne.estimate_noise_level_function(planes, clip_low=clip_low, n_bootstrap=10)
    assert np.all(a.counts + a.rejected + b.counts + b.rejected <= whole.counts + whole.rejected)
    assert a.counts.sum() > 0 and b.counts.sum() > 0
