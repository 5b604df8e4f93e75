"""The report's plain words: p-values as bounds (never 'p 0'), no 'nan', one sentence per cause."""

from __future__ import annotations

import re

import numpy as np
import pytest

from g2r_jax.audit import wording
from g2r_jax.audit.causes import REGISTRY


@pytest.mark.parametrize("p, words", [(0.0, "p < 1e-300"), (5e-4, "p < 0.001"), (3e-12, "p < 1e-11"),
                                      (0.004, "p = 0.004"), (float("nan"), "p unknown")])
def test_p_values_are_bounds(p, words):
    assert wording.p_words(p) == words


def test_no_nan_in_words():
    assert wording.clean("mean = [ nan  0.1 nan]") == "mean = [ n/a  0.1 n/a]"
    for cause in REGISTRY:
        finding = {"cause": cause.name, "difference": [np.nan, 0.02], "p": 0.0, "significant": True}
        text = wording.sentence(finding) + wording.action(finding, {})
        assert not re.search(r"\bnan\b", text) and text.endswith("."), text


def test_action_says_whether_the_fix_was_checked_on_held_out_data():
    kept = {"cause": "noise_model", "kept": True, "gain": {"heldout": "regions"}}
    assert "not fitted on" in wording.action(kept, {"extended_profile": "x.json"})
    assert "g2r-convert --profile x.json" in wording.action(kept, {"extended_profile": "x.json"})
    assert "audit more files" in wording.action(dict(kept, gain={"heldout": False}), {})
