"""Hidden effects must be found: inject an effect of the vocabulary at a random modest magnitude
(the test's own RNG), and require it named first, its parameter recovered and a positive
held-out gain; clean sets give no finding; two effects are both named."""

from __future__ import annotations

import os

import numpy as np
import pytest

from g2r_jax.audit import diagnose, synthetic
from g2r_jax.audit.vocabulary import FILE_CAUSES as CAUSES  # colour_matrix: tests/test_colour_charts.py
from audit_helpers import assert_parameter_close, hidden_effect, measured_set, significant

SEED = int(os.environ.get("G2R_AUDIT_TEST_SEED", "20240607"))


@pytest.fixture(scope="module")
def base():
    return synthetic.demo_profile()


def _check_named_first(cause, base, rng_seed):
    rng = np.random.default_rng(rng_seed)
    truth, magnitude = hidden_effect(cause, rng, base)
    report = diagnose(base, measured_set(truth, rng_seed), seed=rng_seed % 1000)
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
    report = diagnose(base, measured_set(base, SEED), seed=1)
    assert not significant(report), [(f["cause"], f["p"], f["evidence"]) for f in significant(report)]
    assert report["unexplained"] == []


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_clean_sets_false_alarms(seed, base):
    report = diagnose(base, measured_set(base, SEED + 100 + seed), seed=seed)
    assert not significant(report), [(f["cause"], f["evidence"]) for f in significant(report)]


@pytest.mark.slow
def test_two_effects_are_both_named(base):
    rng = np.random.default_rng(SEED + 7)
    causes = rng.choice([c for c in CAUSES if c != "illuminant_distribution"], 2, replace=False)
    truth = base
    for cause in causes:
        truth = synthetic.inject(truth, cause, **synthetic.random_magnitude(cause, rng))
    report = diagnose(base, measured_set(truth, SEED + 7), seed=3)
    named = {f["cause"] for f in significant(report)}
    assert set(causes) <= named, (causes, named)
