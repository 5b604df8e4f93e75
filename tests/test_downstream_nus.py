"""The paper's downstream experiment, reduced: one NUS camera's real images, few CARLA views, the
classic histogram estimator (the full run is benchmarks/downstream_nus.py and the Downstream
validation page)."""

from __future__ import annotations

import numpy as np
import pytest

import g2r_jax
from g2r_jax.downstream.base import real_sets
from g2r_jax.downstream.illuminant import experiment

pytestmark = [pytest.mark.slow, pytest.mark.data]


def test_reduced_nus_experiment_orders_the_rows_like_the_full_run(shared_data):
    from PIL import Image

    real = real_sets.load_nus(shared_data / "estimation" / "nus" / "NikonD40.npz")
    frames = [np.asarray(Image.open(p).convert("RGB")) for p in sorted((shared_data / "cg" / "carla").glob("*.png"))[::6]]
    result = experiment.illuminant_experiment(
        real, g2r_jax.load_profile("NikonD40"), frames, rows=("upi", "fitted", "real", "real_profile_light"),
        estimators=("histogram",), seeds=(0,), n=200)
    mean = {row: result.summary(row, "histogram")["mean"] for row in result.rows}
    assert all(len(e[0]) == len(real.images) for e in result.errors.values())   # every image tested once
    # real training is far better than any synthetic set; real content relit to the fitted model's
    # lights is close to it (the profile's share is small); CG content is what is left
    assert mean["real"] < 0.7 * min(mean["upi"], mean["fitted"])
    assert mean["real_profile_light"] < mean["real"] + 0.6
    assert mean["fitted"] > mean["real_profile_light"] + 1.0
    assert mean["fitted"] < mean["upi"] + 0.5
