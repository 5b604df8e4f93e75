"""One large file is enough, and one clean file raises no alarm (issue 9): single 1000 x 1500
dead-leaves files of the dark, 10-bit `s20fe_night` camera. The scene seeds are the two whose
high ISO (3170 and 1800) made the noise test read the estimator's texture bias as a model error
(x1.11-1.12 over all bins, z up to 20) before the level function's tighter block selection
(`noise_estimation.LEVEL_QUANTILES`); banding must not come back as a noise-model finding once
it is explained away."""

from __future__ import annotations

import numpy as np
import pytest

import g2r_jax
from g2r_jax.audit import diagnose, synthetic
from audit_helpers import measured_set, significant

HEIGHT, WIDTH = 1000, 1500


@pytest.fixture(scope="module")
def camera():
    return g2r_jax.load_profile("s20fe_night")


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 1002])
def test_clean_single_large_file_has_no_finding(camera, seed):
    files = measured_set(camera, seed, n=1, height=HEIGHT, width=WIDTH)
    assert files[0][1].iso > 1500     # the high-ISO files that used to raise the false alarm
    report = diagnose(camera, files, seed=seed)
    assert not significant(report), [(f["cause"], f["evidence"]) for f in significant(report)]


@pytest.mark.slow
def test_banding_in_a_single_file_is_named_once(camera):
    truth = synthetic.inject(camera, "banding", height=HEIGHT, width=WIDTH, std=0.0028, axis="column")
    report = diagnose(camera, measured_set(truth, 0, n=1, height=HEIGHT, width=WIDTH), seed=0)
    named = [f["cause"] for f in significant(report)]
    assert named == ["banding"], named
    assert report["findings"][0]["kept"]
    assert np.isfinite(report["findings"][0]["gain"]["after"])


def _denoised_above(mosaic, info, level, strength):
    """The raw of a camera that denoises in-camera above `level` (fraction of range): each CFA
    plane's pixels above it are pulled towards their 3 x 3 same-colour mean by `strength`."""
    out = np.asarray(mosaic, np.float64).copy()
    black, span = float(np.mean(info.black_level)), float(info.white_level) - float(np.mean(info.black_level))
    for dy in (0, 1):
        for dx in (0, 1):
            plane = out[dy::2, dx::2]
            padded = np.pad(plane, 1, mode="reflect")
            mean = sum(padded[1 + a:1 + a + plane.shape[0], 1 + b:1 + b + plane.shape[1]]
                       for a in (-1, 0, 1) for b in (-1, 0, 1)) / 9
            above = (mean - black) / span > level
            plane[above] = (1 - strength) * plane[above] + strength * mean[above]
    return np.clip(np.rint(out), 0, info.white_level).astype(np.uint16)


@pytest.mark.slow
def test_denoised_single_file_names_a_noise_cause_first(camera):
    rng = np.random.default_rng(19)
    (mosaic, info), = measured_set(camera, 3, n=1, height=HEIGHT, width=WIDTH)
    denoised = _denoised_above(mosaic, info, level=float(rng.uniform(0.02, 0.08)), strength=float(rng.uniform(0.4, 0.8)))
    report = diagnose(camera, [(denoised, info)], seed=3)
    found = significant(report)
    assert found and found[0].get("source", found[0]["cause"]) in ("noise_model", "noise_correlation"), \
        [(f["cause"], f["evidence"][:120]) for f in found]
    assert "black_level" not in [f["cause"] for f in found]
    noise = next(f for f in found if f["cause"] == "noise_model")
    assert noise["kept"] and noise["gain"]["after"] < noise["gain"]["before"], noise["gain"]


@pytest.mark.slow
def test_single_clean_dim_file_raises_no_black_level(camera):
    """A dim scene has no black: its darkest content is not a pedestal."""
    from g2r_jax.audit import scenes, simulate

    dim = scenes.dead_leaves(5, 600, 900) * 0.25 + 0.1   # no black leaf, a fifth of the brightness
    files = simulate.simulate(camera, dim[None], 77)
    report = diagnose(camera, files, seed=5)
    assert "black_level" not in [f["cause"] for f in significant(report)]


def test_noise_clipped_at_zero_dn_is_not_read_as_a_noise_difference():
    """A camera whose black level is 0 DN clips its noise at 0: the share of clipped pixels depends
    on how much of the scene is black, so pairs touching that floor are left out of the noise level
    function (they measure the clipping)."""
    from g2r_jax.audit.stats import noise_level_function

    rng = np.random.default_rng(3)
    sigma = 2e-4
    level = np.where(np.arange(256)[None, :] < 128, 0.0, 0.02) * np.ones((256, 1))  # half the scene black
    planes = np.maximum(level[None] + sigma * rng.standard_normal((4, 256, 256)), 0.0)   # clipped at 0 DN
    variance, mean = noise_level_function(planes, np.ones(4), np.zeros(2))
    assert not np.any(mean < 0.01)                      # the clipped black half is not measured
    bright = np.isfinite(variance)
    assert bright.any() and np.all(np.abs(np.log(variance[bright] / sigma**2)) < 0.2)
