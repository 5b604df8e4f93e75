"""Hidden effects must be found: inject an effect of the vocabulary at a random modest magnitude
(the test's own RNG), and require it named first, its parameter recovered and a positive
held-out gain; clean sets give no finding; two effects are both named. Every measured set holds
three dark frames: the only black-level evidence the audit accepts besides optical-black pixels."""

from __future__ import annotations

import os

import numpy as np
import pytest

from g2r_jax.audit import diagnose, synthetic
from g2r_jax.audit.vocabulary import FILE_CAUSES as CAUSES  # colour_matrix: tests/test_colour_charts.py
from audit_helpers import assert_parameter_close, dark_frames, hidden_effect, measured_set, significant

SEED = int(os.environ.get("G2R_AUDIT_TEST_SEED", "20240607"))


@pytest.fixture(scope="module")
def base():
    return synthetic.demo_profile()


def _check_named_first(cause, base, rng_seed):
    rng = np.random.default_rng(rng_seed)
    truth, magnitude = hidden_effect(cause, rng, base)
    report = diagnose(base, measured_set(truth, rng_seed) + dark_frames(truth, rng_seed), seed=rng_seed % 1000)
    found = significant(report)
    assert found, f"{cause} {magnitude}: nothing significant"
    first = found[0]
    assert first["cause"] == cause, (magnitude, [(f["cause"], f["score"]) for f in found])
    assert first["gain"]["heldout"] and first["gain"]["after"] < first["gain"]["before"], first["gain"]
    assert first["kept"]
    assert_parameter_close(cause, first["params"], magnitude, truth)
    return report


FAST = ("black_level", "lens_shading")


@pytest.mark.parametrize("cause", FAST)
def test_hidden_effect_is_named_first(cause, base):
    _check_named_first(cause, base, SEED + CAUSES.index(cause))


@pytest.mark.slow
@pytest.mark.parametrize("cause", [c for c in CAUSES if c not in FAST])
def test_hidden_effect_is_named_first_slow(cause, base):
    _check_named_first(cause, base, SEED + CAUSES.index(cause))


def test_clean_set_has_no_finding(base):
    report = diagnose(base, measured_set(base, SEED) + dark_frames(base, SEED), seed=1)
    assert not significant(report), [(f["cause"], f["p"], f["evidence"]) for f in significant(report)]
    assert report["unexplained"] == []


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_clean_sets_false_alarms(seed, base):
    report = diagnose(base, measured_set(base, SEED + 100 + seed), seed=seed)
    assert not significant(report), [(f["cause"], f["evidence"]) for f in significant(report)]


def test_simulated_sizes_mirror_the_measured_mix():
    from importlib import import_module

    simulation_sizes = import_module("g2r_jax.audit.runner").simulation_sizes
    mixed = [(120, 180)] * 8 + [(200, 300)] * 8 + [(160, 240)] * 8
    assert sorted(simulation_sizes(mixed, 24)) == [((120, 180), 8), ((160, 240), 8), ((200, 300), 8)]
    assert simulation_sizes([(120, 180)] * 5, 24) == [((120, 180), 24)]
    (size, count), = simulation_sizes([(3000, 4000)], 24)           # scaled to SIMULATION_PIXELS, same aspect
    assert count == 24 and size[0] * size[1] <= 240_000 and abs(size[1] / size[0] - 4 / 3) < 0.01
    many = [(100 + 20 * k, 150 + 30 * k) for k in range(6) for _ in range(k + 1)]
    shares = simulation_sizes(many, 24)
    assert len(shares) == 4 and sum(c for _, c in shares) == 24 and shares[0][0] == (200, 300)


@pytest.mark.parametrize("seed", [1002])
def test_clean_mixed_size_set_has_no_finding(seed, base):
    """Files of three sizes in one audit: a clean set that gave black_level when the simulated
    files all had one size (the dark floor depends on the file's size)."""
    from g2r_jax.audit import scenes, simulate

    measured = []
    for k, (h, w) in enumerate([(120, 180), (200, 300), (160, 240)]):
        measured += simulate.simulate(base, scenes.scene_set(8, 10_000 + seed + 97 * k, h, w), 50_000 + seed + 97 * k)
    report = diagnose(base, measured, seed=seed)
    assert not significant(report), [(f["cause"], f["evidence"]) for f in significant(report)]
    assert sorted(map(tuple, report["simulated_sizes"])) == [(120, 180, 8), (160, 240, 8), (200, 300, 8)]


@pytest.mark.slow
def test_two_effects_are_both_named(base):
    rng = np.random.default_rng(SEED + 7)
    causes = rng.choice([c for c in CAUSES if c != "illuminant_distribution"], 2, replace=False)
    truth = base
    for cause in causes:
        truth = synthetic.inject(truth, cause, **synthetic.random_magnitude(cause, rng))
    report = diagnose(base, measured_set(truth, SEED + 7) + dark_frames(truth, SEED + 7), seed=3)
    named = {f["cause"] for f in significant(report)}
    assert set(causes) <= named, (causes, named)
