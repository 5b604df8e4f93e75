"""A black pedestal in a measured set without dark frames or optical-black pixels (issue 29):
every raw value raised by a constant drawn at random (seeded, 1-6 % of the range). The audit
must name `black_level` first with a held-out gain (the pedestal inferred from the noise curve,
`audit.scene_pedestal`), or name no wrong cause and say that dark frames would decide. The same
sets with the black right but the noise or the exposure wrong must not be called a pedestal."""

from __future__ import annotations

import numpy as np
import pytest

import g2r_jax
from g2r_jax.audit import diagnose, scenes, simulate, synthetic
from audit_helpers import significant

SEED = 29_2026
WRONG = ("noise_model", "exposure_distribution")   # what a pedestal was mistaken for before


@pytest.fixture(scope="module")
def camera():
    """A NikonD5200-like camera: the shipped profile with black 600 and white 16383."""
    return synthetic.levels_replaced(g2r_jax.load_profile("NikonD5200"), 600.0, 16383.0)


def scene_files(truth, seed, n=24, height=120, width=180):
    return simulate.simulate(truth, scenes.scene_set(n, 10_000 + seed, height, width), 50_000 + seed)


def check_pedestal(camera, seed, low=0.01, high=0.06, **size):
    rng = np.random.default_rng(SEED + seed)
    offset = float(rng.uniform(low, high))
    truth = synthetic.inject(camera, "black_level", offset=offset)
    report = diagnose(camera, scene_files(truth, seed, **size), seed=seed)
    found = significant(report)
    assert found, f"offset {offset:.4f}: nothing found"
    first = found[0]
    if first["cause"] == "black_level":
        assert first["kept"] and first["gain"]["heldout"] and first["gain"]["after"] < first["gain"]["before"], first
        assert abs(first["params"]["offset_fraction"] - offset) < 0.15 * offset, (first["params"], offset)
    else:   # the data could not tell: no wrong cause fitted, and the report says what would decide
        assert first["cause"] == "unexplained" and "dark frames" in first["decide_with"], first
    kept_before = [f["cause"] for f in found[:found.index(first)] if f.get("kept")]
    assert not kept_before
    assert not (first["cause"] in WRONG and first.get("kept")), (offset, first["cause"])
    return report


def test_pedestal_without_dark_frames_is_not_called_noise(camera):
    check_pedestal(camera, 0)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(1, 5))
def test_pedestal_without_dark_frames_random_magnitudes(camera, seed):
    check_pedestal(camera, seed, height=192, width=288)


@pytest.mark.slow
def test_clean_camera_without_dark_frames_has_no_pedestal(camera):
    report = diagnose(camera, scene_files(camera, 7), seed=7)
    assert not significant(report), [(f["cause"], f["evidence"]) for f in significant(report)]


@pytest.mark.slow
@pytest.mark.parametrize("cause, magnitude", [("noise_model", {"scale": 0.55}), ("noise_model", {"scale": 1.6}),
                                              ("exposure_distribution", {"stops": 2.5})])
def test_other_causes_are_not_called_a_pedestal(camera, cause, magnitude):
    truth = synthetic.inject(camera, cause, **magnitude)
    report = diagnose(camera, scene_files(truth, 11), seed=11)
    found = significant(report)
    assert found and found[0]["cause"] in (cause, "unexplained"), [(f["cause"], f["evidence"][:200]) for f in found]
    assert not any(f["cause"] == "black_level" for f in found), [(f["cause"], f["evidence"][:200]) for f in found]
