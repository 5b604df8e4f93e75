"""Where a neural ISP's colour error lies (`downstream.isp.error_parts`): a prediction one white
balance away from its target loses its error to the gains, one colour matrix away to the 3 x 3
correction, and a tone error to neither; the masks decide which pixels the corrections see."""

from __future__ import annotations

import numpy as np
import pytest

from g2r_jax.downstream.isp import error_parts
from g2r_jax.downstream.isp.net import delta_e_2000


def _srgb(linear):
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


@pytest.fixture(scope="module")
def target():
    rng = np.random.default_rng(3)
    return _srgb(rng.uniform(0.02, 0.6, (3, 12, 12, 3)))


def _linear(srgb):
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def test_a_white_balance_error_is_the_gains_share(target):
    gains = np.array([0.75, 1.0, 1.25])
    predicted = _srgb(_linear(target) / gains)
    assert np.allclose(error_parts.best_gains(predicted, target), gains, rtol=1e-6)
    parts = error_parts.error_parts(predicted, target)
    assert np.all(delta_e_2000(predicted, target) > 3.0)
    assert np.all(parts["delta_e_balance"] < 1e-3) and np.all(parts["delta_e_colour"] < 1e-3)


def test_a_colour_matrix_error_is_left_by_the_gains_and_taken_by_the_matrix(target):
    matrix = np.array([[0.85, 0.1, 0.05], [0.05, 0.9, 0.05], [0.02, 0.12, 0.86]])
    predicted = _srgb(_linear(target) @ matrix.T)
    parts = error_parts.error_parts(predicted, target)
    assert np.all(parts["delta_e_balance"] > 0.5)
    assert np.all(parts["delta_e_colour"] < 1e-2)


def test_a_tone_error_is_left_in_part_by_both(target):
    predicted = _srgb(_linear(target) ** 1.4)      # the gains take its mean level, not its curve
    plain, parts = delta_e_2000(predicted, target), error_parts.error_parts(predicted, target)
    assert np.all(parts["delta_e_colour"] > 0.2 * plain) and np.all(parts["delta_e_balance"] >= parts["delta_e_colour"] - 1e-9)


def test_the_corrections_see_only_the_masked_pixels(target):
    predicted = _srgb(_linear(target) / np.array([0.8, 1.0, 1.2]))
    spoiled = predicted.copy()
    spoiled[:, :4] = 0.0                   # a wrong region the mask leaves out
    mask = np.ones(target.shape[:3], bool)
    mask[:, :4] = False
    parts = error_parts.error_parts(spoiled, target, mask)
    assert np.all(parts["delta_e_balance"] < 1e-3)
    assert np.all(error_parts.error_parts(spoiled, target)["delta_e_balance"] > 1.0)


def test_an_unknown_correction_is_refused(target):
    with pytest.raises(ValueError, match="unknown correction"):
        error_parts.corrected(target, target, kind="curve")
