"""The cause registry: every cause states its contract, the vocabulary follows the registry, and a
new cause enters the audit by being registered (one class, one registry entry)."""

from __future__ import annotations

import numpy as np

from g2r_jax.audit import CAUSES, causes, diagnose, synthetic
from g2r_jax.audit.causes.base import Cause, effects_replaced
from audit_helpers import measured_set


def test_every_registered_cause_states_what_it_measures_and_how_it_is_validated():
    names = [c.name for c in causes.REGISTRY]
    assert len(set(names)) == len(names)
    for cause in causes.REGISTRY:
        assert cause.name and cause.statistic and cause.tolerance >= 0
        if cause.extensible:
            assert cause.metric
            assert type(cause).fit is not Cause.fit and type(cause).apply is not Cause.apply, cause.name
    assert CAUSES == tuple(c.name for c in causes.REGISTRY if c.extensible)
    assert causes.get("lens_shading") is causes.lens_shading.CAUSE


class _ClipFraction(Cause):
    """A toy cause for the test: fraction of pixels at the clipping level, extension: clip_level."""

    name = "toy_clip_fraction"
    statistic = "clipped fraction"
    metric = "difference of the clipped fraction"
    tolerance = 0.0

    def vectors(self, files, profile):
        return np.stack([[np.isfinite(f["clip"]).mean()] for f in files])

    def fit(self, measured, simulated, profile, *, seed=0):
        return {"clip_level": 0.9}

    def apply(self, profile, params):
        return effects_replaced(profile, clip_level=profile.effects.clip_level * 0 + params["clip_level"])


def test_a_registered_cause_is_tested_and_reported():
    base = synthetic.demo_profile()
    measured = measured_set(base, 3, n=6, height=60, width=90)
    registry = causes.REGISTRY[:1] + (_ClipFraction(),)
    report = diagnose(base, measured, seed=0, n_simulated=6, causes=registry, n_permutations=200)
    assert {f["cause"] for f in report["findings"]} == {"illuminant_distribution", "toy_clip_fraction"}
    assert report["tests"] == 2
