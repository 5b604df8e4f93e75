"""Other cameras' lights carried into a camera (illuminants/pooled.py), leave-one-camera-out."""

import json

import jax
import numpy as np
import pytest

from g2r_jax.illuminants import choice as ch
from g2r_jax.illuminants import distributions as il
from g2r_jax.illuminants import pooled as po
from g2r_jax.profile.schema import load_profile


def test_leaving_a_camera_out_removes_its_lights_and_every_source_weighs_the_same():
    pool = po.load_pooled()
    colour = load_profile("NikonD40").colour
    everyone = po.carried_lights(colour, pool=pool)
    without = po.carried_lights(colour, exclude=("NikonD40",), pool=pool)
    assert "NikonD40" in everyone.sources and "NikonD40" not in without.sources
    assert len(without.chromaticities) == len(everyone.chromaticities) - len(pool["NikonD40"])
    np.testing.assert_allclose(without.weights.sum(), 1.0)
    # equal total weight per source camera: a camera's share is 1 / (number of sources)
    start = 0
    for name in without.sources:
        share = without.weights[start:start + len(pool[name])].sum()
        np.testing.assert_allclose(share, 1.0 / len(without.sources), rtol=1e-9)
        start += len(pool[name])


def test_a_camera_s_own_lights_come_back_through_its_own_matrices(shared_data):
    """The pool stores each light as (mired, Duv) through its camera's own matrices; carried back
    into that camera they are its measured chromaticities again (the DNG fixed point, inverted)."""
    colour = load_profile("NikonD40").colour
    measured = np.load(shared_data / "estimation" / "nus" / "NikonD40.npz")["illuminants"]
    pool = {"NikonD40": po.load_pooled()["NikonD40"]}
    back = po.carried_lights(colour, pool=pool)
    assert back.left_out == 0.0
    # the shipped profile carries the same Adobe A/D65 pair as the pool's source; 4-decimal storage
    np.testing.assert_allclose(back.chromaticities, il.neutral_to_chromaticity(measured), atol=2e-3)


def test_pooled_model_blends_the_camera_s_lights_with_the_pool():
    colour = load_profile("Canon600D").colour
    none, words = ch.fit_pooled_for_camera(np.zeros((0, 2)), colour, exclude=("Canon600D",))
    assert none.kind == "kernel" and "measured cameras" in words
    samples = il.neutral_to_chromaticity(np.asarray(il.sample_neutrals(jax.random.PRNGKey(0), none, 2000), np.float64))
    assert np.all(samples > 0) and np.all(np.isfinite(samples))
    lights = np.array([[0.5, 0.6], [0.52, 0.58], [0.8, 0.35]])
    blended, words = ch.fit_pooled_for_camera(lights, colour, exclude=("Canon600D",))
    own = np.asarray(blended.weights)[:3]
    np.testing.assert_allclose(own.sum(), 3 / (3 + 5), rtol=1e-5)   # n / (n + n0), n0 = PRIOR_PSEUDO_LIGHTS
    np.testing.assert_allclose(np.asarray(blended.means)[:3], lights, rtol=1e-6)
    choice = ch.choose_illuminant_model(lights, colour, "pooled")
    assert choice.lights == 3 and "measured cameras" in choice.reason


def test_a_malformed_pool_names_its_file(tmp_path):
    bad = tmp_path / "pool.json"
    bad.write_text(json.dumps({"cameras": {"A": [[1.0]]}}))
    with pytest.raises(ValueError, match="pool.json"):
        po.load_pooled(bad)
    bad.write_text(json.dumps({"no cameras": 1}))
    with pytest.raises(ValueError, match="pool.json"):
        po.load_pooled(bad)
    with pytest.raises(ValueError, match="no pooled lights left"):
        po.carried_lights(load_profile("Canon600D").colour, exclude=("A",), pool={"A": np.array([[150.0, 0.0]])})
