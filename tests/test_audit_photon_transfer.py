"""The audit against photon transfer: synthetic bursts whose truth is known (dim and textured
scenes, fixed-pattern noise, 10 and 14 bits, rounding to DN; `g2r_jax.audit.synthetic_bursts`).
With the true profile the audit finds nothing; with one cause injected it names that cause first
and its extension gains on held-out data. Bursts are tested on the sensor's causes: the frames
of one scene are one draw of exposure and illuminant, which says little about their
distributions."""

from __future__ import annotations

import numpy as np
import pytest

import g2r_jax
from g2r_jax.audit import black_evidence, bursts, diagnose
from g2r_jax.measure.photon_transfer import temporal_nlf
from g2r_jax.audit.causes import BY_NAME
from g2r_jax.audit.evidence import nlf_edges
from g2r_jax.audit.synthetic_bursts import BurstTruth, burst, scene_signal, truth_profile
from g2r_jax.measure.dark_frames import is_dark_frame

SENSOR = [BY_NAME[c] for c in ("noise_model", "black_level", "white_level", "green_imbalance", "lens_shading",
                               "defective_pixels", "banding")]
TEN_BIT = BurstTruth(black_tag=64, white=1023, shot=0.8 / 80 / 959, read=1.2 / 959**2, prnu=0.01, dsnu_dn=0.3)
FOURTEEN_BIT = BurstTruth(black_tag=512, white=16383, shot=2e-5, read=4e-7, iso=200, prnu=0.005, dsnu_dn=1.0)
HEIGHT, WIDTH = 256, 384


def _significant(report):
    return [f for f in report["findings"] if f["significant"]]


def test_temporal_noise_is_the_truth_despite_fixed_pattern_noise():
    """Photon transfer over 8 frames: the binned temporal variance matches shot x + read + 1/12 DN^2
    within its standard errors, although the frames carry 1 % PRNU and 0.3 DN DSNU."""
    truth = TEN_BIT
    signal = scene_signal(1, 128, 192, low=0.01, high=0.2, fine=True)
    frames = [bursts.frame_planes(m, i.black_level, i.white_level, 0.0) for m, i in burst(truth, signal, 8, seed=2)]
    found = temporal_nlf(np.stack(frames), pedestal=np.zeros(4), clip=np.full(4, 0.9),
                                clip_low=np.full(4, -0.05), edges=nlf_edges())["all"]
    ok = np.isfinite(found.variance)
    model = truth.shot * found.signal + truth.read + 1 / 12 / truth.span**2
    z = (found.variance - model) / found.se
    assert ok.sum() >= 12 and np.all(np.abs(z[ok]) < 4.5), z[ok]


def test_dark_frames_and_scenes_are_told_apart():
    truth = BurstTruth(**{**TEN_BIT.__dict__, "pedestal": 2.0})
    dim = burst(truth, scene_signal(3, 128, 192, low=0.004, high=0.03), 1, seed=1, n_dark=1)
    (scene, info), (dark, _) = dim
    assert not is_dark_frame(scene, info.black_level, info.white_level)
    assert is_dark_frame(dark, info.black_level, info.white_level)
    found = black_evidence.file_evidence(dark, info, info.black_level, truth.span)
    assert found["source"] == "dark frame" and np.allclose(found["offset"], 2.0, atol=0.1)
    assert black_evidence.file_evidence(scene, info, info.black_level, truth.span) is None


def test_optical_black_margin_is_evidence():
    truth = BurstTruth(**{**TEN_BIT.__dict__, "pedestal": 1.5, "margin": 32})
    (mosaic, info), = burst(truth, scene_signal(3, 128, 192), 1, seed=1)
    found = black_evidence.file_evidence(mosaic, info, info.black_level, truth.span)
    assert found["source"] == "optical black" and np.allclose(found["offset"], 1.5, atol=0.15)


@pytest.mark.slow
@pytest.mark.parametrize("truth, low, high, fine, seed", [
    (TEN_BIT, 0.004, 0.06, False, 1),      # dim: the darkest content 4 DN above black
    (TEN_BIT, 0.01, 0.5, True, 2),         # textured, bright
    (FOURTEEN_BIT, 0.002, 0.05, True, 3),
    (FOURTEEN_BIT, 0.01, 0.6, False, 4),
])
def test_true_profile_no_finding(truth, low, high, fine, seed):
    files = burst(truth, scene_signal(seed, HEIGHT, WIDTH, low=low, high=high, fine=fine), 8, seed=seed)
    report = diagnose(truth_profile(g2r_jax.load_profile("s20fe_night"), truth), files, seed=seed, causes=SENSOR)
    assert report["bursts"] and len(report["bursts"][0]) == 8
    assert not _significant(report), [(f["cause"], f["evidence"]) for f in _significant(report)]


@pytest.mark.slow
@pytest.mark.parametrize("truth, seed", [(TEN_BIT, 5), (FOURTEEN_BIT, 6)])
def test_injected_noise_is_named_first_with_a_heldout_gain(truth, seed):
    files = burst(truth, scene_signal(seed, HEIGHT, WIDTH, low=0.004, high=0.1), 8, seed=seed, noise_scale=1.6)
    report = diagnose(truth_profile(g2r_jax.load_profile("s20fe_night"), truth), files, seed=seed, causes=SENSOR)
    first = report["findings"][0]
    assert first["cause"] == "noise_model" and first["significant"] and first["kept"], report["findings"][:2]
    assert first["gain"]["after"] < 0.5 * first["gain"]["before"]
    assert np.allclose(first["params"]["shot_scale"], 1.6, rtol=0.15)


@pytest.mark.slow
@pytest.mark.parametrize("margin, n_dark", [(0, 3), (32, 0)])
def test_injected_pedestal_is_named_from_dark_frames_or_optical_black(margin, n_dark):
    truth = BurstTruth(**{**TEN_BIT.__dict__, "pedestal": 3.0, "margin": margin})
    files = burst(truth, scene_signal(7, HEIGHT, WIDTH, low=0.004, high=0.06), 8, seed=7, n_dark=n_dark)
    report = diagnose(truth_profile(g2r_jax.load_profile("s20fe_night"), truth, pedestal=0.0), files, seed=7,
                      causes=SENSOR)
    named = [f["cause"] for f in _significant(report)]
    assert named == ["black_level"], [(f["cause"], f["evidence"]) for f in _significant(report)]
    first = report["findings"][0]
    assert first["kept"] and first["gain"]["after"] < first["gain"]["before"]
    assert np.allclose(first["params"]["black_pedestal_dn"], 3.0, atol=0.2)


def test_quiet_integer_dark_frame_is_a_dark_frame():
    """Read noise of 0.4 DN: most neighbour differences are 0 DN, and a MAD-based noise scale is
    0; the dark frame must still be recognised (else it counts as a black scene)."""
    truth = BurstTruth(**{**TEN_BIT.__dict__, "read": 0.16 / 959**2, "prnu": 0.0, "dsnu_dn": 0.0})
    (dark, info), = burst(truth, np.zeros((120, 180)), 0, seed=3, n_dark=1)
    assert is_dark_frame(dark, info.black_level, info.white_level)
