"""Illuminant models: hull rejection, mixtures, the single-DNG locus, S20 FE night data."""

import csv

import jax
import numpy as np
import pytest

from g2r_jax.illuminants import distributions as il
from g2r_jax.colour.dng_model import DngColourModel
from g2r_jax.profile.schema import load_profile

CANON_A = np.array([0.7164, -0.1916, -0.0431, -0.3361, 1.06, 0.32, -0.0272, 0.1058, 0.6442]).reshape(3, 3)
CANON_D65 = np.array([0.6461, -0.0907, -0.0882, -0.43, 1.2184, 0.2378, -0.0819, 0.1944, 0.5931]).reshape(3, 3)


def s20_illuminants(shared_data):
    with open(shared_data / "illuminants" / "s20fe_night_graycard_45.csv") as handle:
        return np.array([[float(r["r_over_g"]), float(r["b_over_g"])] for r in csv.DictReader(handle)])


def test_gaussian_samples_stay_inside_the_hull():
    rng = np.random.default_rng(0)
    points = rng.normal([0.5, 0.6], [0.08, 0.1], (30, 2))
    model = il.fit_gaussian(points)
    samples = np.asarray(il.sample_neutrals(jax.random.PRNGKey(1), model, 4000))[:, [0, 2]]
    assert np.all(np.asarray(il.inside_hull(samples, model.hull, 1e-6)))
    np.testing.assert_allclose(samples.mean(0), points.mean(0), atol=0.03)


def test_mixture_finds_two_separated_populations_and_a_gaussian_does_not():
    rng = np.random.default_rng(1)
    points = np.concatenate([rng.normal([0.45, 0.7], 0.02, (40, 2)), rng.normal([1.2, 0.25], 0.02, (20, 2))])
    mixture = il.fit_mixture(points)
    assert len(mixture.weights) == 2
    np.testing.assert_allclose(sorted(np.asarray(mixture.weights)), [1 / 3, 2 / 3], atol=0.05)
    held_out = np.concatenate([rng.normal([0.45, 0.7], 0.02, (40, 2)), rng.normal([1.2, 0.25], 0.02, (20, 2))])
    gaussian = il.fit_gaussian(points)
    assert il.mixture_log_likelihood(mixture, held_out).mean() > il.mixture_log_likelihood(gaussian, held_out).mean() + 1


def test_single_dng_locus_samples_lie_along_the_locus_between_A_and_D65():
    model = DngColourModel.from_tags((17, 21), [CANON_A, CANON_D65], dtype=np.float64)
    locus = il.locus_chromaticities(model, 64)
    locus_model = il.fit_locus(model)
    samples = np.asarray(il.sample_neutrals(jax.random.PRNGKey(2), locus_model, 3000))[:, [0, 2]]
    length = np.sum(np.linalg.norm(np.diff(locus, axis=0), axis=1))
    distance = np.min(np.linalg.norm(samples[:, None] - locus[None], axis=-1), axis=1)
    assert np.median(distance) < 0.1 * length
    # the warm end (A: high r/g, low b/g) and the cool end are both reached
    assert samples[:, 0].max() > locus[:, 0].max() - 0.05 * length
    assert samples[:, 0].min() < locus[:, 0].min() + 0.05 * length
    assert locus[0, 0] > locus[-1, 0] and locus[0, 1] < locus[-1, 1]  # A is redder and less blue than D65


def test_too_few_illuminants_raise_a_clear_error():
    with pytest.raises(ValueError, match="at least 3"):
        il.fit_gaussian(np.array([[0.5, 0.5], [0.6, 0.6]]))
    with pytest.raises(ValueError, match="collinear"):
        il.convex_hull_halfplanes(np.array([[0.5, 0.5], [0.6, 0.6], [0.7, 0.7]]))


def test_energy_distance_is_zero_for_identical_samples_and_grows_with_shift():
    rng = np.random.default_rng(3)
    a = rng.normal(0, 1, (200, 2))
    assert abs(il.energy_distance(a, a)) < 1e-12
    assert il.energy_distance(a, a + 0.5) < il.energy_distance(a, a + 1.0)


@pytest.mark.data
def test_s20fe_night_profile_samples_are_as_close_as_the_published_recipe(shared_data):
    """Energy distance to the 45 measured night illuminants: the shipped profile vs the published
    recipe (one Gaussian fitted after dropping the sodium lamps, r/g > 1, hull of the rest)."""
    measured = s20_illuminants(shared_data)
    published = il.fit_gaussian(measured[measured[:, 0] <= 1.0])
    shipped = load_profile("s20fe_night").illuminants
    ours, theirs = [], []
    for seed in range(5):
        key = jax.random.PRNGKey(seed)
        ours.append(il.energy_distance(np.asarray(il.sample_neutrals(key, shipped, 1500))[:, [0, 2]], measured))
        theirs.append(il.energy_distance(np.asarray(il.sample_neutrals(key, published, 1500))[:, [0, 2]], measured))
    assert np.mean(ours) <= np.mean(theirs)


@pytest.mark.data
def test_sodium_lamps_are_sampled_by_the_shipped_profile(shared_data):
    measured = s20_illuminants(shared_data)
    samples = np.asarray(il.sample_neutrals(jax.random.PRNGKey(0), load_profile("s20fe_night").illuminants, 5000))
    measured_share = np.mean(measured[:, 0] > 1.0)
    assert measured_share > 0.1
    assert np.mean(samples[:, 0] > 1.0) > 0.5 * measured_share
