"""Issue 29: read noise when dark frames are at hand, and without them. A black frame simulated
from a profile fitted by `fit_profile` on a synthetic S20 FE-like burst (10-bit, black 60, read
terms that differ per CFA site, no NoiseProfile, integer raws) holds, per CFA site, the variance of
the sensor's own dark frames: within 10 % when the folder holds its dark frames, within 15 %
without them (`tests/dark_frame_sensors.py`; figures: benchmarks/read_noise_dark_frames.py)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dark_frame_sensors import dark_variance, frames, s20fe, simulated_black_variance, write_folder
from g2r_jax.audit.synthetic_bursts import scene_signal
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
from g2r_jax.profile.fitting import fit_profile
from g2r_jax.audit.black_evidence import file_evidence
from g2r_jax.measure.bursts import is_static_burst
from g2r_jax.measure.dark_frames import dark_frame_statistics, is_dark_frame
from g2r_jax.sensor.dark_frames import read_from_dark_frames
from g2r_jax.sensor.noise.quantisation import rounded_gaussian_variance, variance_before_rounding

pytestmark = pytest.mark.skipif(not __import__("dark_frame_sensors").TABLE.exists(),
                                reason="../shared/data is not present (the S20 FE noise calibration)")


def _fit(paths, notes=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_profile([read_dng_info(p) for p in paths], notes=notes)


def _ratios(tmp_path, iso, seed, with_dark, **size):
    truth = s20fe(iso)
    burst, darks = write_folder(tmp_path, truth, seed=seed, **size)
    real = dark_variance([read_dng_pixels(p) for p in darks])
    notes = []
    profile = _fit(burst + darks if with_dark else burst, notes)
    return simulated_black_variance(profile, iso) / real, profile, notes


@pytest.mark.parametrize("iso, seed", [(100.0, 1), (1600.0, 2)])
def test_black_frame_matches_dark_frames_when_they_are_at_hand(tmp_path, iso, seed):
    ratio, profile, notes = _ratios(tmp_path, iso, seed, True, height=128, width=192, n_frames=4, n_dark=4)
    assert np.all(np.abs(ratio - 1) < 0.10), ratio
    assert "read term from 4 dark frame(s)" in profile.info.provenance
    assert len(notes) == 1 and notes[0].startswith("4 dark frame(s)") and "read noise" in notes[0]


@pytest.mark.parametrize("iso, seed", [(400.0, 3), (3200.0, 4)])
def test_black_frame_matches_dark_frames_without_them(tmp_path, iso, seed):
    """No dark frame in the folder: the burst's temporal noise gives the read term."""
    ratio, profile, notes = _ratios(tmp_path, iso, seed, False, height=192, width=288, n_frames=8, n_dark=3)
    assert np.all(np.abs(ratio - 1) < 0.15), ratio
    assert "temporal" in profile.info.provenance and not notes


@pytest.mark.slow
@pytest.mark.parametrize("iso", [100.0, 200.0, 400.0, 800.0, 1600.0, 3200.0])
@pytest.mark.parametrize("with_dark, tolerance", [(True, 0.10), (False, 0.15)])
def test_black_frame_across_isos(tmp_path, iso, with_dark, tolerance):
    ratio, _, _ = _ratios(tmp_path, iso, int(iso) % 7, with_dark)
    assert np.all(np.abs(ratio - 1) < tolerance), ratio


def test_dark_frames_stay_out_of_the_illuminant_fit(tmp_path):
    """A dark frame's AsShotNeutral says nothing of the scene's light: the illuminants of the
    profile fitted with dark frames are those fitted without them."""
    burst, darks = write_folder(tmp_path, s20fe(800.0), n_frames=4, n_dark=2, height=64, width=96)
    with_dark, without = _fit(burst + darks), _fit(burst)
    np.testing.assert_array_equal(np.asarray(with_dark.illuminants.means), np.asarray(without.illuminants.means))


def test_detector_tells_dark_frames_from_dim_scenes():
    truth = s20fe(1600.0, dsnu_dn=0.3, hot_fraction=2e-4, row_banding_dn=1.0)
    dim = scene_signal(5, 128, 192, low=0.004, high=0.03)
    mosaics = frames(truth, dim, 2, 2, seed=5)
    black, white = np.full(4, truth.black), truth.white
    assert [is_dark_frame(m, black, white) for m in mosaics] == [False, False, True, True]
    quiet = frames(s20fe(100.0), np.zeros((128, 192)), 0, 1, seed=6)[0]     # 0.44-0.5 DN: mostly 0 and +-1
    assert is_dark_frame(quiet, black, white)


def test_the_audit_takes_black_level_evidence_from_the_same_dark_frames():
    """One detector (`g2r_jax.measure.dark_frames`): the audit's black-level evidence is the dark
    frames profile fitting finds, and none from a dim scene."""
    truth = s20fe(1600.0, dsnu_dn=0.3, hot_fraction=2e-4, row_banding_dn=1.0)
    mosaics = frames(truth, scene_signal(5, 128, 192, low=0.004, high=0.03), 1, 2, seed=9)
    black, span = np.full(4, truth.black), truth.white - np.full(4, truth.black)
    info = type("Info", (), {"path": ""})()
    found = [file_evidence(m, info, black, span) for m in mosaics]
    assert found[0] is None and [f["source"] for f in found[1:]] == ["dark frame", "dark frame"]
    assert [is_dark_frame(m, black, truth.white) for m in mosaics] == [False, True, True]


def test_hot_pixels_and_banding_do_not_throw_the_read_noise():
    """Hot pixels are left out; row banding is part of what a dark frame shows and is kept, and
    measured as a share of the variance."""
    clean = s20fe(800.0)
    noisy = s20fe(800.0, hot_fraction=5e-4, row_banding_dn=0.8)
    shape = np.zeros((256, 384))
    reference = dark_variance(frames(clean, shape, 0, 3, seed=7))
    stats = [dark_frame_statistics(m) for m in frames(noisy, shape, 0, 3, seed=7)]
    found = read_from_dark_frames(stats, np.full(4, 60.0), 1023.0)
    expected = reference + 0.8**2
    assert np.all(np.abs(found.variance_dn2 / expected - 1) < 0.08), found.variance_dn2 / expected
    assert found.hot_fraction > 2e-4
    assert np.all(np.abs(found.banding_share - 0.8**2 / expected) < 0.1), found.banding_share


@pytest.mark.parametrize("sigma, offset", [(0.3, 0.0), (0.45, 0.0), (0.45, 0.4), (2.0, 0.2)])
def test_rounding_is_undone_exactly(sigma, offset):
    rng = np.random.default_rng(8)
    measured = np.rint(60 + offset + sigma * rng.standard_normal(2_000_000)).var()
    assert abs(rounded_gaussian_variance(sigma, offset) / measured - 1) < 0.01
    assert abs(np.sqrt(variance_before_rounding(measured, offset)) / sigma - 1) < 0.01


def test_unrelated_files_are_not_a_burst():
    truth = s20fe(800.0)
    scenes = [frames(truth, scene_signal(s, 128, 192), 1, 0, seed=s)[0] for s in range(4)]
    assert not is_static_burst(scenes)
    assert is_static_burst(frames(truth, scene_signal(1, 128, 192), 4, 0, seed=1))


def test_cli_says_it_took_the_read_noise_from_the_dark_frames(tmp_path, capsys):
    from g2r_jax.cli.fit_profile import main

    write_folder(tmp_path / "dngs", s20fe(1600.0), n_frames=4, n_dark=3, height=64, width=96)
    assert main([str(tmp_path / "dngs"), "-o", str(tmp_path / "p.json")]) == 0
    lines = [l for l in capsys.readouterr().err.splitlines() if "dark frame" in l]
    assert len(lines) == 1 and lines[0].startswith("g2r-fit-profile: note: 3 dark frame(s)"), lines
    assert "took the read noise per CFA site from them" in lines[0]
