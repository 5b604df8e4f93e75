"""The denoising downstream test (g2r_jax.downstream.denoising, .bursts) on synthetic bursts whose
noise is known: burst reading names and skips bad files, photon transfer and the reference's
noise correction recover the truth, and a denoiser trained with the true noise beats one
trained with a noise 4x too low on the same (content-equal) scene."""

from __future__ import annotations

import dataclasses
import shutil

import jax
import numpy as np
import pytest

import g2r_jax
from g2r_jax.audit.synthetic_bursts import BurstTruth, truth_profile
from g2r_jax.downstream import bursts, denoising
from g2r_jax.io.dng_info import DngError

SPAN = 959.0
TRUTH = BurstTruth(black_tag=64.0, white=1023.0, shot=2.3e-3, read=1.1e-5, iso=1600.0)


@pytest.fixture(scope="module")
def base_profile():
    return g2r_jax.load_profile("s20fe_night")


@pytest.fixture(scope="module")
def true_profile(base_profile):
    return truth_profile(base_profile, TRUTH)


@pytest.fixture(scope="module")
def burst_folder(tmp_path_factory, true_profile):
    """8 frames of a dim 96 x 128 scene with the known noise TRUTH."""
    folder = tmp_path_factory.mktemp("burst")
    _, truth = bursts.write_synthetic_burst(folder, true_profile, n_frames=8, height=96, width=128, iso=1600, seed=3)
    assert truth.shot == pytest.approx(TRUTH.shot, rel=1e-5) and truth.read == pytest.approx(TRUTH.read, rel=1e-5)
    return folder


def test_read_burst_names_and_skips_bad_files(tmp_path, burst_folder, true_profile):
    folder = tmp_path / "mixed"
    shutil.copytree(burst_folder, folder)
    (folder / "notes.txt").write_text("not a frame")
    (folder / "broken.dng").write_bytes(b"II*\x00 not a real DNG")
    bursts.write_synthetic_burst(tmp_path / "small", true_profile, n_frames=1, height=64, width=128, seed=3)
    shutil.copy(tmp_path / "small" / "frame_000.dng", folder / "other_size.dng")
    bursts.write_synthetic_burst(tmp_path / "moved", true_profile, n_frames=1, height=96, width=128, seed=11)
    shutil.copy(tmp_path / "moved" / "frame_000.dng", folder / "other_scene.dng")

    burst = bursts.read_burst(folder)
    assert burst.n == 8 and burst.names == tuple(f"frame_{k:03d}.dng" for k in range(8))
    reasons = dict(burst.skipped)
    assert set(reasons) == {"notes.txt", "broken.dng", "other_size.dng", "other_scene.dng"}
    assert "not a DNG" in reasons["notes.txt"]
    assert "size 128x64 differs from the burst's 128x96" in reasons["other_size.dng"]
    assert "not the same static scene" in reasons["other_scene.dng"]
    assert burst.iso == 1600 and burst.white == 1023 and np.all(burst.black == 64)


def test_read_burst_refuses_fewer_than_three_frames(tmp_path, burst_folder):
    paths = [burst_folder / "frame_000.dng", burst_folder / "frame_001.dng", tmp_path / "missing.dng"]
    with pytest.raises(DngError, match=r"at least 3 DNG frames.*2 usable.*missing\.dng: no such file"):
        bursts.read_burst(paths)


def test_photon_transfer_recovers_the_known_noise(burst_folder):
    shot, read = bursts.photon_transfer_noise(bursts.read_burst(burst_folder))
    assert np.allclose(shot, TRUTH.shot, rtol=0.12), shot
    assert np.allclose(read, TRUTH.read, rtol=0.25), read


def test_reference_noise_is_taken_out_of_the_psnr(burst_folder):
    """Frame vs mean of the others: the corrected PSNR is that of the frame's own noise, whose
    variance we know (truth at the scene's signal, plus rounding); uncorrected it is lower by
    10 log10(1 + 1/(n-1))."""
    burst = bursts.read_burst(burst_folder)
    clean = burst.planes.mean(0)
    true_variance = float(np.mean(TRUTH.shot * np.maximum(clean, 0) + TRUTH.read)) + 1 / 12 / SPAN**2
    expected = 10 * np.log10(1 / true_variance)
    corrected = [denoising.psnr(burst.planes[i], *denoising.reference_and_variance(burst, i)) for i in range(burst.n)]
    raw = [denoising.psnr(burst.planes[i], denoising.reference_and_variance(burst, i)[0]) for i in range(burst.n)]
    others = np.delete(burst.planes, 2, axis=0).astype(np.float64)
    reference, variance = denoising.reference_and_variance(burst, 2)
    assert np.allclose(reference, others.mean(0), atol=1e-7)
    assert variance == pytest.approx(np.mean(others.var(0, ddof=1)) / 7, rel=1e-6)
    assert np.mean(corrected) == pytest.approx(expected, abs=0.15)
    assert np.mean(corrected) - np.mean(raw) == pytest.approx(10 * np.log10(1 + 1 / 7), abs=0.1)


def test_synthetic_noise_has_the_model_variance_and_is_deterministic():
    spec = denoising.NoiseSpec(shot=np.full(4, 2e-3, np.float32), read=np.full(4, 1e-5, np.float32))
    clean = np.full((64, 4, 16, 16), 0.05, np.float32)
    levels = (np.full(4, 64.0, np.float32), np.full(4, SPAN, np.float32), np.float32(1023))
    draw = jax.jit(lambda key: denoising.synthetic_noisy(key, clean, denoising._noise_arrays(spec), False, 0.5,
                                                         *levels))
    noisy = np.asarray(draw(jax.random.PRNGKey(0)))
    expected = 0.5 * (2e-3 * 0.05 + 1e-5) + 1 / 12 / SPAN**2
    assert noisy.var() == pytest.approx(expected, rel=0.05)
    assert np.allclose(np.round(noisy * SPAN), noisy * SPAN, atol=1e-3)    # on the DN grid
    assert np.array_equal(noisy, np.asarray(draw(jax.random.PRNGKey(0))))
    assert not np.array_equal(noisy, np.asarray(draw(jax.random.PRNGKey(1))))


def test_training_is_deterministic(burst_folder):
    burst = bursts.read_burst(burst_folder)
    targets = np.stack([burst.mean_of_others(i, range(4)) for i in range(4)])

    def losses(seed):
        return denoising.train_denoiser(jax.random.PRNGKey(seed), burst, targets, inputs=burst.planes[:4], gain=8.0,
                                        steps=3)[1]

    assert np.array_equal(losses(5), losses(5))
    assert not np.array_equal(losses(5), losses(6))


def test_denoising_in_strips_equals_the_whole_frame(monkeypatch):
    params = denoising.init_denoiser(jax.random.PRNGKey(0))
    planes = np.random.default_rng(0).uniform(0, 0.1, (4, 50, 24)).astype(np.float32)
    whole = np.asarray(denoising._denoise(params, planes, 8.0))
    monkeypatch.setattr(denoising, "TILE", 16)
    assert np.allclose(denoising.denoise(params, planes, 8.0), whole, rtol=0, atol=1e-6)


def test_profile_of_another_cfa_is_refused(burst_folder, true_profile):
    from g2r_jax.profile import schema

    other = schema.replace(true_profile, cfa_pattern=np.asarray([2, 1, 1, 0]))
    with pytest.raises(ValueError, match=r"CFA pattern \(2, 1, 1, 0\) is not the burst's \(0, 1, 1, 2\)"):
        denoising.denoising_benchmark(burst_folder, other, rows=("truth",), contents=("scene",), seeds=(0,), steps=1)


def _four_times_too_low(burst_folder, true_profile, base_profile, rows, steps, seeds):
    burst = bursts.read_burst(burst_folder)
    low = truth_profile(base_profile, dataclasses.replace(TRUTH, shot=TRUTH.shot / 4, read=TRUTH.read / 4))
    kwargs = dict(contents=("scene",), seeds=seeds, steps=steps)
    good = denoising.denoising_benchmark(burst, true_profile, rows=rows, **kwargs)
    wrong = denoising.denoising_benchmark(burst, low, rows=("shipped",), **kwargs)
    return good, np.mean(wrong.psnr[("shipped", "scene")])


@pytest.mark.slow
def test_true_noise_beats_a_noise_four_times_too_low(burst_folder, true_profile, base_profile):
    """Content-equal: the same scene, the same training; only the noise model differs. The true
    profile beats one whose noise is 4x too low (both trainings share one compiled step; about
    50 s on a loaded 2-core machine, hence slow)."""
    good, too_low = _four_times_too_low(burst_folder, true_profile, base_profile, ("shipped",), 150, (0,))
    shipped = good.psnr[("shipped", "scene")][0]
    assert shipped > too_low + 1.0, (shipped, too_low)
    assert shipped > good.noisy_psnr + 1.0
    assert "| g2r_jax shipped profile |" in good.table()


@pytest.mark.slow
def test_true_noise_beats_a_noise_four_times_too_low_longer(burst_folder, true_profile, base_profile):
    """As above with the photon-transfer truth and the real pairs, 300 steps and two seeds: the
    truth and the true profile are within 0.3 dB of each other and both 1 dB or more above the
    4x-too-low model; the real pairs beat the noisy input by over 1 dB."""
    good, too_low = _four_times_too_low(burst_folder, true_profile, base_profile, ("shipped", "truth", "real"), 300,
                                        (0, 1))
    shipped, truth = (np.mean(good.psnr[(r, "scene")]) for r in ("shipped", "truth"))
    assert shipped > too_low + 1.0 and truth > too_low + 1.0, (shipped, truth, too_low)
    assert abs(shipped - truth) < 0.3
    assert np.mean(good.psnr[("real", "scene")]) > good.noisy_psnr + 1.0
    assert "photon transfer over the 8 frames" in good.summary()


@pytest.mark.slow
@pytest.mark.data
def test_benchmark_all_rows_on_cg_and_scene(burst_folder, true_profile, shared_data):
    """Every row and content on CARLA frames: finite PSNRs above the noisy input, one per seed."""
    cg = sorted((shared_data / "cg" / "carla").glob("*.png"))[:8]
    result = denoising.denoising_benchmark(burst_folder, true_profile, cg, seeds=(0, 1), steps=150, cg_count=8)
    assert set(result.psnr) == {(r, c) for r in denoising.ROWS for c in denoising.CONTENTS} - {("real", "cg")}
    for key, values in result.psnr.items():
        assert len(values) == 2 and np.all(np.isfinite(values)), key
    assert result.psnr[("truth", "scene")][0] > result.noisy_psnr + 1.0
    assert result.cg_images == 8
