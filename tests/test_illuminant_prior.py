"""The camera-independent illuminant prior: (mired, Duv) coordinates, the shipped parameters,
the mapping into a camera's (r/g, b/g), and (with ../shared/data) leave-one-camera-out."""

import importlib.util
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax.colour import dng_model as dng
from g2r_jax.colour.spectrum_locus import is_light_chromaticity
from g2r_jax.illuminants import distributions as D
from g2r_jax.illuminants import prior as P
from g2r_jax.illuminants.mired_duv import DUV_SCALE, MIRED_RANGE, mired_duv_to_xy, xy_to_mired_duv
from g2r_jax.illuminants.prior_fit import fit_population, prior_to_dict
from g2r_jax.runtime.x64 import enable_x64

# Canon EOS 600D-like Adobe pair (Standard Light A, D65), rounded: any plausible camera works here
CM_A = np.array([0.7164, -0.1916, -0.0431, -0.3361, 1.06, 0.32, -0.0272, 0.1058, 0.6442]).reshape(3, 3)
CM_D65 = np.array([0.6461, -0.0907, -0.0882, -0.43, 1.2184, 0.2378, -0.0819, 0.1944, 0.5931]).reshape(3, 3)


def camera(dtype=np.float64):
    return dng.DngColourModel.from_tags((17, 21), [CM_A, CM_D65], dtype=dtype)


def test_mired_duv_inverts_and_agrees_with_ohno_2013():
    import colour

    points = np.stack(np.meshgrid(np.linspace(80, 600, 14), np.linspace(-25, 25, 11)), -1).reshape(-1, 2)
    xy = np.asarray(mired_duv_to_xy(jnp.asarray(points)))
    np.testing.assert_allclose(xy_to_mired_duv(xy), points, atol=2e-3)
    reference = colour.temperature.uv_to_CCT_Ohno2013(colour.xy_to_UCS_uv(xy))
    near = np.abs(points[:, 1]) <= 10   # where real lights are (Ohno's method is approximate beyond)
    np.testing.assert_allclose(1e6 / reference[near, 0], points[near, 0], atol=0.5)   # Krystek vs Planck's law
    np.testing.assert_allclose(reference[near, 1] * DUV_SCALE, points[near, 1], atol=0.3)


def test_shipped_prior_loads_with_positive_parameters_and_its_presets():
    prior = P.load_prior()
    assert {"day", "night", "day_night"} <= set(prior.presets) and prior.duv_spread > 0
    assert "Gehler-Shi" in prior.source and "S20 FE" in prior.source
    for preset in prior.presets:
        weights, means, covariances = prior.mixture(preset)
        assert abs(weights.sum() - 1) < 1e-12 and np.all(np.linalg.eigvalsh(covariances) > 0)
        assert np.all((means[:, 0] > MIRED_RANGE[0]) & (means[:, 0] < MIRED_RANGE[1]))


def test_a_malformed_prior_names_its_source_and_field():
    document = prior_to_dict(P.load_prior())
    del document["duv_spread"]
    with pytest.raises(ValueError, match="mine.json.*duv_spread"):
        P.prior_from_dict(document, "mine.json")
    document = prior_to_dict(P.load_prior())
    document["presets"]["day"] = {"moonlight": 1.0}
    with pytest.raises(ValueError, match="mine.json.*'day'.*moonlight"):
        P.prior_from_dict(document, "mine.json")
    with pytest.raises(ValueError, match="unknown illuminant prior preset 'dusk'"):
        P.load_prior().mixture("dusk")


@pytest.mark.slow
def test_samples_in_a_camera_are_finite_physical_lights_of_the_prior():
    """Every preset, sampled in a camera: finite positive neutrals whose white (solved back through
    the camera's DNG model) is a light (inside the spectrum locus) within the prior's support."""
    with enable_x64():
        model = camera()
        neutrals = np.concatenate([np.asarray(P.sample_neutrals_for(jax.random.PRNGKey(1), model, 500, preset))
                                   for preset in ("day", "night", "day_night")])
        assert np.all(np.isfinite(neutrals)) and np.all(neutrals > 0)
        xy, converged = dng.camera_neutrals_to_xy(jnp.asarray(neutrals), model)
    xy = np.asarray(xy)
    assert np.all(np.asarray(converged))
    assert all(is_light_chromaticity(p, margin=0.003) for p in xy)   # the support stops at the locus
    points = xy_to_mired_duv(xy)
    assert np.all((points[:, 0] > 0.9 * MIRED_RANGE[0]) & (points[:, 0] < 1.1 * MIRED_RANGE[1]))
    assert np.all(np.abs(points[:, 1]) < 1.2 * P.DUV_LIMIT * DUV_SCALE)


@pytest.mark.slow
def test_the_camera_mixture_reproduces_the_prior_in_mired_and_duv():
    """The linearised, split mapping loses nothing that matters: lights sampled in the camera and
    solved back to xy through the DNG model have the prior's own quantiles."""
    prior = P.load_prior()
    with enable_x64():
        model = camera()
        neutrals = P.sample_neutrals_for(jax.random.PRNGKey(2), model, 4000, "day_night", prior)
        xy, _ = dng.camera_neutrals_to_xy(neutrals, model)
    through_camera = xy_to_mired_duv(np.asarray(xy))
    direct = P.sample_mired_duv(prior, 4000, "day_night", seed=3)
    for q in (10, 50, 90):
        assert abs(np.percentile(through_camera[:, 0], q) - np.percentile(direct[:, 0], q)) < 8, q
        assert abs(np.percentile(through_camera[:, 1], q) - np.percentile(direct[:, 1], q)) < 0.6, q


def test_a_camera_whose_matrices_fail_on_most_of_the_prior_is_refused():
    """A matrix whose blue response turns negative for every light warmer than ~6000 K cannot
    carry the prior: a clear error, no silent truncation."""
    broken = CM_D65.copy()
    broken[2] = [0.0, -0.5, 0.55]
    with enable_x64():
        model = dng.DngColourModel.from_tags((21,), [broken], dtype=np.float64)
        with pytest.raises(ValueError, match="non-positive"):
            P.model_for_camera(model, "day")


def test_weighted_mixture_fit_recovers_two_populations():
    rng = np.random.default_rng(0)
    a = rng.multivariate_normal([160, 2], [[300, 0], [0, 4]], 400)
    b = rng.multivariate_normal([360, -3], [[900, 0], [0, 2]], 100)
    points = np.concatenate([a, b])
    weights = np.concatenate([np.full(400, 0.5 / 400), np.full(100, 0.5 / 100)])   # two "cameras", equal say
    fit = fit_population(points, weights)
    assert len(fit["weights"]) == 2
    order = np.argsort(fit["means"][:, 0])
    means = fit["means"][order]
    assert np.all(np.abs(means[:, 0] - [160, 360]) < 6) and np.all(np.abs(means[:, 1] - [2, -3]) < 0.5), means
    np.testing.assert_allclose(fit["weights"][order], [0.5, 0.5], atol=0.05)


def test_profile_json_round_trip_keeps_the_prior_kind(tmp_path):
    from g2r_jax.profile.fitting import fit_profile
    from g2r_jax.profile.schema import load_profile, save_profile
    from g2r_jax.io.dng_info import DngInfo

    info = DngInfo(path="x.dng", cfa_pattern=(0, 1, 1, 2), black_level=np.zeros(4), white_level=4095.0,
                   calibration_illuminants=(17, 21), color_matrices=(CM_A, CM_D65), unique_camera_model="Cam",
                   as_shot_neutral=np.array([0.5, 1, 0.6]))
    profile = fit_profile([info], illuminant_model="prior")
    save_profile(profile, tmp_path / "p.json")
    loaded = load_profile(tmp_path / "p.json")
    assert loaded.illuminants.kind == "prior" and loaded.illuminants.use_hull
    samples = np.asarray(D.sample_neutrals(jax.random.PRNGKey(0), loaded.illuminants, 200))
    assert np.all(np.isfinite(samples)) and np.all(samples > 0)


# ------------------------------------------------------------------------ measured data

def _benchmark():
    spec = importlib.util.spec_from_file_location("illuminant_prior_benchmark", Path("benchmarks/illuminant_prior.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.data
@pytest.mark.slow
def test_leave_one_camera_out_the_prior_beats_the_s3_locus_on_every_camera(shared_data):
    from g2r_jax.illuminants.prior_fit import measured_sets

    benchmark = _benchmark()
    with enable_x64():
        rows = benchmark.leave_one_camera_out(measured_sets(shared_data), presets=("day",))
    cameras = {r["camera"] for r in rows}
    assert len(cameras) == 3
    for name in cameras:
        by_model = {r["model"].split(" (")[0]: r for r in rows if r["camera"] == name}
        prior, locus = by_model["prior 'day'"], by_model["S3 locus"]
        assert name not in prior["trained_on"]
        assert prior["energy"] < locus["energy"], (name, prior, locus)
        assert prior["coverage"] >= locus["coverage"], (name, prior, locus)


@pytest.mark.data
@pytest.mark.slow
def test_shipped_prior_is_what_its_sources_give(shared_data, tmp_path):
    from g2r_jax.illuminants.prior_fit import main

    assert main([str(shared_data), str(tmp_path / "prior.json")]) == 0
    refit = json.loads((tmp_path / "prior.json").read_text())
    shipped = prior_to_dict(P.load_prior())
    assert refit["presets"] == shipped["presets"] and refit["source"] == shipped["source"]
    for name, population in shipped["populations"].items():
        for key, value in population.items():
            np.testing.assert_allclose(refit["populations"][name][key], value, rtol=1e-4, atol=1e-4)
