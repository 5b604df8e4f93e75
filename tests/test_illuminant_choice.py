"""The kernel illuminant model (illuminants/kernel.py) and the choice of model (illuminants/choice.py)."""

import csv

import jax
import numpy as np
import pytest

from g2r_jax.illuminants import choice as ch
from g2r_jax.illuminants import distributions as il
from g2r_jax.illuminants import kernel as kd
from g2r_jax.profile.schema import load_profile, replace, save_profile


def arc(count, rng, across=0.004):
    """Lights on a quarter circle (a curved band like the Planckian locus in r/g, b/g), the band's
    own polyline and the lights' tangents."""
    angle = rng.uniform(0.0, np.pi / 2, count)
    radial = 0.5 + rng.normal(0.0, across, count)
    points = 0.2 + np.stack([radial * np.cos(angle), radial * np.sin(angle)], -1)
    grid = np.linspace(0.0, np.pi / 2, 200)
    polyline = 0.2 + 0.5 * np.stack([np.cos(grid), np.sin(grid)], -1)
    return points, polyline, kd.locus_tangents(points, polyline)


def samples_of(model, n=4000, seed=1):
    return il.neutral_to_chromaticity(np.asarray(il.sample_neutrals(jax.random.PRNGKey(seed), model, n), np.float64))


def test_locus_tangents_follow_the_polyline():
    points, polyline, tangents = arc(50, np.random.default_rng(0))
    centre_direction = (points - 0.2) / np.linalg.norm(points - 0.2, axis=1, keepdims=True)
    # on a circle the tangent is perpendicular to the radius
    assert np.max(np.abs(np.sum(tangents * centre_direction, axis=1))) < 0.02
    np.testing.assert_allclose(np.linalg.norm(tangents, axis=1), 1.0, atol=1e-12)


def test_leave_one_out_bandwidths_are_narrow_across_the_band_and_wide_along_it():
    rng = np.random.default_rng(1)
    points = np.stack([rng.uniform(0.3, 0.9, 150), 0.5 + rng.normal(0.0, 0.004, 150)], -1)
    tangents = np.tile([1.0, 0.0], (150, 1))
    along, across = kd.choose_bandwidths(points, tangents)
    assert 0.002 < across < 0.008          # the band's own spread (0.004), up to the grid
    assert along > 2 * across
    best = kd.leave_one_out_log_likelihood(points, tangents, along, across)
    assert best > kd.leave_one_out_log_likelihood(points, tangents, along, along)   # isotropic is worse
    assert kd.choose_bandwidths(points[:3], tangents[:3]) == kd.DEFAULT_BANDWIDTHS   # too few to cross-validate


def test_kernel_model_stays_on_a_curved_band_where_the_gaussian_fills_its_hull():
    points, polyline, tangents = arc(120, np.random.default_rng(2))
    kernel = kd.fit_kernel(points, tangents)
    gaussian = il.fit_gaussian(points)
    assert kernel.kind == "kernel" and len(kernel.weights) == len(points)

    def off_band(samples):   # distance from the arc of radius 0.5
        return np.abs(np.linalg.norm(samples - 0.2, axis=1) - 0.5)

    kernel_off, gaussian_off = off_band(samples_of(kernel)), off_band(samples_of(gaussian))
    assert np.median(kernel_off) < 0.3 * np.median(gaussian_off)
    held_out, _, _ = arc(400, np.random.default_rng(3))
    assert (il.energy_distance(samples_of(kernel)[:1500], held_out)
            < 0.5 * il.energy_distance(samples_of(gaussian)[:1500], held_out))


def test_kernel_model_samples_inside_jit_and_vmap():
    points, _, tangents = arc(30, np.random.default_rng(4))
    model = kd.fit_kernel(points, tangents)
    keys = jax.random.split(jax.random.PRNGKey(5), 64)
    batched = jax.jit(jax.vmap(il.sample_chromaticity, in_axes=(0, None)))(keys, model)
    one_by_one = np.stack([np.asarray(il.sample_chromaticity(k, model)) for k in keys[:4]])
    assert batched.shape == (64, 2) and np.all(np.isfinite(batched)) and np.all(np.asarray(batched) > 0)
    np.testing.assert_allclose(np.asarray(batched[:4]), one_by_one, rtol=1e-5)


def test_kernel_blend_gives_the_prior_its_share():
    points, _, tangents = arc(5, np.random.default_rng(6))
    far_prior = il._model([1.0], [[2.0, 2.0]], [1e-4 * np.eye(2)], None, "prior", False, np.float32)
    model = kd.fit_kernel(points, tangents, prior=far_prior, prior_lights=5.0)
    share = np.mean(np.linalg.norm(samples_of(model) - 2.0, axis=1) < 0.1)
    assert abs(share - 0.5) < 0.03          # n0 / (n + n0) = 5 / 10


def test_kernel_rejects_bad_lights():
    with pytest.raises(ValueError, match="at least one"):
        kd.fit_kernel(np.zeros((0, 2)), np.zeros((0, 2)))
    with pytest.raises(ValueError, match="positive"):
        kd.fit_kernel(np.array([[0.5, -0.1]]), np.array([[1.0, 0.0]]))


@pytest.fixture(scope="module")
def canon():
    return load_profile("Canon600D")


@pytest.mark.slow
def test_auto_takes_the_kernel_from_enough_lights_and_the_pooled_lights_below(canon):
    no_light = ch.choose_illuminant_model(np.zeros((0, 2)), canon.colour)
    assert no_light.reason.startswith("pooled (auto") and no_light.lights == 0 and "0 measured lights" in no_light.reason
    lights = np.array([[0.46, 0.66], [0.48, 0.64], [0.52, 0.60], [0.62, 0.52], [0.45, 0.67], [0.75, 0.42],
                       [0.47, 0.65], [0.50, 0.62], [0.55, 0.57], [0.58, 0.55], [0.68, 0.47], [0.44, 0.68]])
    for count in (1, 2, 5, ch.MIN_LIGHTS_FOR_KERNEL - 1, 12):
        chosen = ch.choose_illuminant_model(lights[:count], canon.colour)
        expected = "kernel (auto" if count >= ch.MIN_LIGHTS_FOR_KERNEL else "pooled (auto"
        assert chosen.model.kind == "kernel" and chosen.reason.startswith(expected), chosen.reason
        assert chosen.lights == count and f"{count} measured light" in chosen.reason
        samples = samples_of(chosen.model, 2000)
        assert np.all(np.isfinite(samples)) and np.all(samples > 0)
    for count in (1, 2, 5):   # asked for, the kernel model takes any number of lights
        kernel = ch.choose_illuminant_model(lights[:count], canon.colour, "kernel")
        assert kernel.model.kind == "kernel" and len(kernel.model.weights) > count
        samples = samples_of(kernel.model, 2000)
        assert np.all(np.isfinite(samples)) and np.all(samples > 0)
        near = np.min(np.linalg.norm(samples[:, None] - lights[None, :count], axis=-1), axis=1) < 0.03
        assert near.mean() > 0.5 * count / (count + kd.PRIOR_PSEUDO_LIGHTS)   # the lights' own share
    with pytest.raises(ValueError, match="unknown illuminant model"):
        ch.choose_illuminant_model(lights, canon.colour, "guess")
    with pytest.raises(ValueError, match="at least 3 distinct"):
        ch.choose_illuminant_model(lights[:2], canon.colour, "gaussian")


@pytest.mark.slow
def test_kernel_profile_round_trips_through_save_and_load(tmp_path, canon):
    lights = np.array([[0.46, 0.66], [0.48, 0.64], [0.52, 0.60], [0.62, 0.52], [0.45, 0.67], [0.75, 0.42],
                       [0.47, 0.65]])
    model = ch.choose_illuminant_model(lights, canon.colour, "kernel").model
    profile = replace(canon, illuminants=model)
    save_profile(profile, tmp_path / "kernel.json")
    loaded = load_profile(tmp_path / "kernel.json").illuminants
    assert loaded.kind == "kernel" and loaded.use_hull == model.use_hull
    for field in ("weights", "means", "cholesky", "hull"):
        np.testing.assert_allclose(np.asarray(getattr(loaded, field)), np.asarray(getattr(model, field)),
                                   rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(samples_of(loaded, 500), samples_of(model, 500), rtol=1e-4, atol=1e-6)


def night_lights(shared_data):
    with open(shared_data / "illuminants" / "s20fe_night_graycard_105.csv") as handle:
        return np.array([[float(r["r_over_g"]), float(r["b_over_g"])] for r in csv.DictReader(handle)])


@pytest.mark.data
@pytest.mark.slow
def test_night_lights_keep_their_sodium_lamps_in_the_kernel_model(shared_data):
    measured = night_lights(shared_data)
    chosen = ch.choose_illuminant_model(measured, load_profile("s20fe_night").colour, "auto")
    assert chosen.model.kind == "kernel" and "night" in chosen.reason
    samples = samples_of(chosen.model, 5000)
    sodium = np.mean(measured[:, 0] > 1.0)
    assert sodium > 0.03                      # 6 of the 105
    assert abs(np.mean(samples[:, 0] > 1.0) - sodium) < 0.3 * sodium


@pytest.mark.slow
def test_audit_magnitude_is_the_energy_distance_and_ranks_a_hull_filling_gaussian_above_the_kernel(canon):
    from g2r_jax.audit.causes.illuminant_distribution import CAUSE, DEGREES_PER_ENERGY

    points, _, tangents = arc(60, np.random.default_rng(7))
    files = [{"neutral": np.array([r, 1.0, b])} for r, b in points]
    found = {}
    for name, model in (("gaussian", il.fit_gaussian(points)), ("kernel", kd.fit_kernel(points, tangents))):
        found[name] = CAUSE.test(files, [], replace(canon, illuminants=model), n_permutations=200)
        assert f"{DEGREES_PER_ENERGY * found[name]['magnitude']:.2g} deg" in found[name]["evidence"]
    assert found["gaussian"]["magnitude"] > 3 * found["kernel"]["magnitude"] > 0
