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


@pytest.mark.parametrize("cause, difference, words", [
    ("lens_shading", [-0.3, -0.1, 0.05, -0.2], "26 % darker"),     # exp(-0.3) = 0.74
    ("lens_shading", [0.2, 0.1, 0.05, 0.1], "22 % brighter"),
    ("white_level", [-0.077, -0.05, -0.05, -0.001], "7.7 % of the range below"),
    ("exposure_distribution", [-1.9], "1.9 stops darker"),
    ("exposure_distribution", [0.5], "0.5 stops brighter"),
])
def test_sentences_say_which_way_the_difference_goes(cause, difference, words):
    """Issue 19: 'brighter or darker' left the user to guess; the sign of the largest component decides."""
    text = wording.sentence({"cause": cause, "difference": difference})
    assert words in text and "brighter or darker" not in text, text


def test_black_level_sentence_gives_one_offset_when_all_positions_agree():
    text = wording.sentence({"cause": "black_level", "difference_dn": [76.77, 76.73, 76.81, 76.75]})
    assert "76.77 DN above where the profile puts it" in text, text
    text = wording.sentence({"cause": "black_level", "difference_dn": [2.0, -1.0, 0.5, 0.0]})
    assert "+2.00, -1.00, +0.50, +0.00 DN (per CFA position)" in text, text


def test_noise_sentence_gives_the_range_over_signal_levels():
    finding = {"cause": "noise_model", "worst": {"ratio": 0.45, "level": 0.021},
               "ratio_by_level": [[0.0078, 1.0], [0.021, 0.45], [0.45, 0.099]]}
    text = wording.sentence(finding)
    assert "x0.45 the profile's at 2.1 %" in text and "from x0.099 (at 45 %) to x1.00 (at 0.78 %)" in text, text


def test_titles_name_the_cause_in_words_and_as_in_the_json():
    assert wording.title({"cause": "noise_model"}) == "Noise (noise_model)"
    unexplained = {"cause": "unexplained", "source": "noise_correlation", "candidate": None}
    assert wording.title(unexplained) == "Correlated noise (noise_correlation)"
    assert wording.status(unexplained) == "not explained" and wording.status({"cause": "x", "kept": True}) == \
        "fixed by the extended profile"
