"""The downstream check's sentence names a difference between rows only when the seeds agree on
it: an illuminant CNN trained twice on the same lights differed by 0.74 deg (sd) per fold on the
NUS benchmark (docs validation illuminant_models, "How fine this benchmark can see")."""

import numpy as np

from g2r_jax.downstream.illuminant.experiment import ExperimentResult
from g2r_jax.downstream.illuminant.reporting import seeds_apart, sentence


def _result(seed_means: dict, seeds=(0, 1)) -> ExperimentResult:
    """Rows whose per-seed errors are 20 images at the given means (one mean per seed)."""
    errors = {(row, "cnn"): [np.full(20, m) for m in means[:len(seeds)]] for row, means in seed_means.items()}
    return ExperimentResult(camera="test", rows=tuple(seed_means), estimators=("cnn",), seeds=tuple(seeds),
                            errors=errors)


def test_overlapping_seeds_are_called_within_training_noise_and_separate_ones_are_not():
    overlapping = _result({"fitted": [4.6, 5.2], "upi": [4.9, 5.6], "real": [2.4, 2.6],
                           "real_profile_light": [2.5, 2.9]})
    text = sentence(overlapping, "cnn")
    assert seeds_apart(overlapping, "fitted", "upi", "cnn") is False
    assert "UPI 5.25, within training noise of g2r_jax" in text, text
    assert "is the profile (colour and lights) (within training noise)" in text, text

    separate = _result({"fitted": [4.6, 4.8], "upi": [6.5, 6.9], "real": [2.4, 2.5],
                        "real_profile_light": [3.4, 3.6]})
    text = sentence(separate, "cnn")
    assert seeds_apart(separate, "fitted", "upi", "cnn") is True
    assert "within training noise" not in text and "UPI 6.70" in text, text
    assert "1.05 is the profile (colour and lights) and" in text, text


def test_one_seed_says_the_training_noise_is_not_measured():
    one = _result({"fitted": [4.6], "upi": [6.5]}, seeds=(0,))
    assert seeds_apart(one, "fitted", "upi", "cnn") is None
    text = sentence(one, "cnn")
    assert "one seed: the training noise is not measured" in text and "within training noise" not in text, text
