"""The denoising check (g2r_jax.downstream.denoising.burst_check, .denoiser, .bursts) on synthetic bursts whose
noise is known: burst reading names and skips bad files (copies, black frames, saturation),
photon transfer and the reference's noise correction recover the truth, the verdict sentence
names only differences larger than the seeds' spread, and (slow) on a dim defocused 10-bit burst
and a bright one the check ranks real pairs >= truth >= the others content-equal."""

from __future__ import annotations

import dataclasses
import shutil

import jax
import numpy as np
import pytest

import g2r_jax
from g2r_jax.audit.synthetic_bursts import BurstTruth, truth_profile
from g2r_jax.downstream.denoising import burst_check, bursts, denoiser, noise
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
    corrected = [burst_check.psnr(burst.planes[i], *burst_check.reference_and_variance(burst, i)) for i in range(burst.n)]
    raw = [burst_check.psnr(burst.planes[i], burst_check.reference_and_variance(burst, i)[0]) for i in range(burst.n)]
    others = np.delete(burst.planes, 2, axis=0).astype(np.float64)
    reference, variance = burst_check.reference_and_variance(burst, 2)
    assert np.allclose(reference, others.mean(0), atol=1e-7)
    assert variance == pytest.approx(np.mean(others.var(0, ddof=1)) / 7, rel=1e-6)
    assert np.mean(corrected) == pytest.approx(expected, abs=0.15)
    assert np.mean(corrected) - np.mean(raw) == pytest.approx(10 * np.log10(1 + 1 / 7), abs=0.1)


def test_synthetic_noise_has_the_model_variance_and_is_deterministic():
    spec = noise.NoiseSpec(shot=np.full(4, 2e-3, np.float32), read=np.full(4, 1e-5, np.float32))
    clean = np.full((64, 4, 16, 16), 0.05, np.float32)
    levels = (np.full(4, 64.0, np.float32), np.full(4, SPAN, np.float32), np.float32(1023))
    draw = jax.jit(lambda key: noise.synthetic_noisy(key, clean, noise._noise_arrays(spec), False, 0.5,
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
    short = denoiser.DenoiserTraining(batch=4, steps_per_round=3)

    def losses(seed):
        return denoiser.train_denoiser(jax.random.PRNGKey(seed), targets, inputs=burst.planes[:4], gain=8.0,
                                       steps=3, training=short).losses

    assert np.array_equal(losses(5), losses(5))
    assert not np.array_equal(losses(5), losses(6))


def test_denoising_in_strips_equals_the_whole_frame(monkeypatch):
    model = denoiser.init_denoiser(jax.random.PRNGKey(0))
    planes = np.random.default_rng(0).uniform(0, 0.1, (4, 50, 24)).astype(np.float32)
    whole = np.asarray(denoiser._denoise(model, planes, 8.0))
    monkeypatch.setattr(denoiser, "TILE", 16)
    assert np.allclose(denoiser.denoise(model, planes, 8.0), whole, rtol=0, atol=1e-6)


def test_profile_of_another_cfa_is_refused(burst_folder, true_profile):
    from g2r_jax.profile import schema

    other = schema.replace(true_profile, cfa_pattern=np.asarray([2, 1, 1, 0]))
    with pytest.raises(ValueError, match=r"CFA pattern \(2, 1, 1, 0\) is not the burst's \(0, 1, 1, 2\)"):
        burst_check.run_burst_check(burst_folder, other, rows=("truth",), contents=("scene",), seeds=(0,), steps=1)


# ---------------------------------------------------------------- degenerate bursts (issue 34's fuzz classes)


def test_a_black_frame_is_named_and_left_out(tmp_path, true_profile):
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
    from g2r_jax.io.dng_write import write_dng

    paths, _ = bursts.write_synthetic_burst(tmp_path, true_profile, n_frames=6, height=64, width=96, seed=4)
    info = read_dng_info(paths[2])
    black = np.full_like(read_dng_pixels(paths[2], info), int(TRUTH.black_tag))
    write_dng(paths[2], black, info)
    burst = bursts.read_burst(tmp_path)
    assert burst.n == 5 and "frame_002.dng" not in burst.names
    assert "a black frame" in dict(burst.skipped)["frame_002.dng"]


def test_identical_frames_are_refused_for_want_of_temporal_noise(tmp_path, true_profile):
    paths, _ = bursts.write_synthetic_burst(tmp_path / "one", true_profile, n_frames=1, height=64, width=96, seed=4)
    folder = tmp_path / "six"
    folder.mkdir()
    for k in range(6):
        shutil.copy(paths[0], folder / f"copy_{k}.dng")
    with pytest.raises(DngError, match=r"six.*no temporal noise between identical frames.*copy_1\.dng: the same "
                                       r"pixels as copy_0\.dng"):
        bursts.read_burst(folder)


def test_a_copied_frame_is_left_out_and_the_rest_kept(tmp_path, burst_folder):
    folder = tmp_path / "copied"
    shutil.copytree(burst_folder, folder)
    shutil.copy(folder / "frame_003.dng", folder / "frame_003_copy.dng")
    burst = bursts.read_burst(folder)
    assert burst.n == 8 and dict(burst.skipped) == {"frame_003_copy.dng": "the same pixels as frame_003.dng: a copy, "
                                                                          "not another exposure"}


def test_a_saturated_burst_is_refused_up_front_naming_its_folder(tmp_path, true_profile):
    folder = tmp_path / "bright_folder"
    bursts.write_synthetic_burst(folder, true_profile, n_frames=4, height=64, width=96, seed=4, low=0.99, high=1.2)
    with pytest.raises(DngError, match=r"bright_folder.*reach the white level.*saturated burst"):
        bursts.read_burst(folder)


# ---------------------------------------------------------------- the verdict


def _result(psnr, seeds=(0, 1, 2)):
    return burst_check.DenoisingResult(psnr=psnr, psnr_uncorrected=psnr, noisy_psnr=30.0, noise={}, frames=("a",),
                                       skipped=(), iso=100.0, folds=2, seeds=seeds, steps=900, cg_images=0,
                                       seconds={}, peak=0.06)


def test_compare_rows_names_only_differences_beyond_the_seeds_spread():
    assert burst_check.compare_rows([40.0, 40.2, 40.1], [39.0, 39.1, 38.9]) == "+1.10 dB"
    assert burst_check.compare_rows([39.0, 39.1, 38.9], [40.0, 40.2, 40.1]) == "-1.10 dB"
    assert burst_check.compare_rows([40.0, 41.0], [40.5, 40.6]) == "within training noise (-0.05 dB)"
    assert "training noise not measured" in burst_check.compare_rows([40.0], [39.0])


def test_verdict_sentence_says_within_training_noise_where_the_rows_overlap():
    result = _result({("fitted", "scene"): [40.0, 40.3, 40.1], ("real", "scene"): [40.2, 39.9, 40.4],
                      ("upi", "scene"): [38.0, 38.2, 37.9], ("fitted", "cg"): [37.0, 37.1, 37.2],
                      ("upi", "cg"): [36.9, 37.5, 37.0]})
    sentence = result.sentence()
    assert "real scene (content-equal): g2r_jax fitted from the burst 40.13 dB" in sentence
    assert "real pairs (cross-validated) 40.17 (within training noise (-0.03 dB))" in sentence
    assert "UPI noise (Brooks 2019) 38.03 (+2.10 dB)" in sentence
    assert "CG content: g2r_jax fitted from the burst 37.10 dB against UPI noise (Brooks 2019) 37.13 (within " \
           "training noise" in sentence
    assert "99.9th percentile" in sentence and sentence in result.summary()


def test_verdict_refuses_to_rank_rows_when_the_denoisers_learn_nothing_or_did_not_converge():
    learned_nothing = _result({("truth", "scene"): [30.2, 30.3], ("real", "scene"): [30.1, 30.4],
                               ("upi", "scene"): [29.9, 30.0]}, seeds=(0, 1))
    assert "NO VERDICT" in learned_nothing.sentence() and "0.25 dB over the noisy input" in learned_nothing.sentence()
    stopped_early = dataclasses.replace(_result({("truth", "scene"): [33.0, 33.2], ("real", "scene"): [33.1, 33.3],
                                                 ("upi", "scene"): [34.0, 34.1]}, seeds=(0, 1)),
                                        step_curve=(-30.0, -31.0, -31.5))
    assert "NO VERDICT" in stopped_early.sentence() and "before the real pairs converged" in stopped_early.sentence()
    assert "0.50 dB in the last round" in stopped_early.sentence() and "NOT converged" in stopped_early.summary()
    converged = dataclasses.replace(stopped_early, step_curve=(-30.0, -31.0, -31.01))
    assert "NO VERDICT" not in converged.sentence()
    # stopped by patience: the last round gains on the one before it, not on the best round
    patience = dataclasses.replace(stopped_early, step_curve=(-51.86, -51.878, -51.845, -51.848, -51.883))
    assert "NO VERDICT" not in patience.sentence() and "converged)" in patience.summary()


def test_cg_content_is_brought_to_the_scene_levels():
    rng = np.random.default_rng(0)
    cg = rng.uniform(0, 1, (3, 4, 32, 32)).astype(np.float32) ** 2
    scene = 0.02 + 0.04 * rng.uniform(0, 1, (4, 32, 32)) ** 3
    matched = burst_check.match_levels(cg, scene)
    for planes in matched:
        assert np.quantile(planes, 0.5) == pytest.approx(np.quantile(scene, 0.5), rel=1e-4)
        assert np.quantile(planes, 0.99) == pytest.approx(np.quantile(scene, 0.99), rel=1e-4)
    assert matched.min() >= 0.0


# ---------------------------------------------------------------- dim and bright bursts of known truth (slow)

DIM = BurstTruth(black_tag=60.0, white=1023.0, shot=5.2e-4, read=2.4e-6, iso=100.0)


def _ranked_check(tmp_path, base_profile, truth, low, high, blur):
    """The check on a burst of known truth: rows truth, UPI, a profile with 4x too little noise,
    real pairs; content-equal; two seeds; steps chosen by validation (the product's cap); 256 x 384
    frames, so that each fold's two training means hold more than 48 x 64 planes of content."""
    folder = tmp_path / "burst"
    profile = truth_profile(base_profile, truth)
    bursts.write_synthetic_burst(folder, profile, n_frames=8, height=256, width=384, iso=truth.iso, seed=5,
                                 low=low, high=high, fine=False, blur=blur)
    low_noise = truth_profile(base_profile, dataclasses.replace(truth, shot=truth.shot / 4, read=truth.read / 4))
    burst = bursts.read_burst(folder)
    assert all(info.noise_profile is None for info in burst.infos)
    result = burst_check.run_burst_check(burst, low_noise, rows=("upi", "shipped", "truth", "real"),
                                         contents=("scene",), seeds=(0, 1), max_steps=burst_check.MAX_STEPS,
                                         truth_noise=(truth.shot, truth.read))
    print(result.summary())   # the figures of docs/pages/validation/downstream_denoising.md (pytest -rP)
    return result


def _assert_ranked(result):
    psnr = {row: result.psnr[(row, "scene")] for row in ("upi", "shipped", "truth", "real")}
    not_below = lambda a, b: np.mean(psnr[a]) >= np.mean(psnr[b]) or "within" in burst_check.compare_rows(psnr[a], psnr[b])
    assert not_below("real", "truth"), psnr
    for other in ("upi", "shipped"):
        assert not_below("truth", other), (other, psnr)
    assert np.mean(psnr["truth"]) > result.noisy_psnr + burst_check.MIN_LEARNED_DB, (psnr, result.noisy_psnr)
    assert result.step_curve and result.last_round_gain() <= burst_check.MIN_GAIN_DB, result.step_curve
    assert "NO VERDICT" not in result.sentence(), result.sentence()


@pytest.mark.slow
def test_dim_defocused_burst_ranks_real_pairs_then_truth(tmp_path, base_profile):
    """10-bit, black 60, white 1023, scene 13-60 DN above black, defocused, no NoiseProfile."""
    result = _ranked_check(tmp_path, base_profile, DIM, 13 / 963, 60 / 963, blur=3.0)
    _assert_ranked(result)


@pytest.mark.slow
def test_bright_defocused_burst_ranks_real_pairs_then_truth(tmp_path, base_profile):
    """The same sensor, the scene at 10-80 % of the range."""
    result = _ranked_check(tmp_path, base_profile, DIM, 0.1, 0.8, blur=3.0)
    _assert_ranked(result)


@pytest.mark.slow
def test_bright_sharp_burst_gets_no_verdict(tmp_path, base_profile):
    """In focus, the dead leaves' edges are texture at the noise's scale: no denoiser gains on the
    noisy input (all rows within 0.1 dB of it when measured), and the check says it cannot rank."""
    result = _ranked_check(tmp_path, base_profile, DIM, 0.1, 0.8, blur=0.0)
    assert result.learned("scene") < burst_check.MIN_LEARNED_DB, result.psnr
    assert "NO VERDICT" in result.sentence() and "no denoiser gains more than" in result.sentence()


@pytest.mark.slow
@pytest.mark.data
def test_check_all_rows_on_cg_and_scene(burst_folder, true_profile, shared_data):
    """Every row and content on CARLA frames: finite PSNRs, one per seed."""
    cg = sorted((shared_data / "cg" / "carla").glob("*.png"))[:4]
    result = burst_check.run_burst_check(burst_folder, true_profile, cg, seeds=(0, 1), steps=200, cg_count=4)
    assert set(result.psnr) == {(r, c) for r in burst_check.ROWS for c in burst_check.CONTENTS} - {("real", "cg")}
    for key, values in result.psnr.items():
        assert len(values) == 2 and np.all(np.isfinite(values)), key
    assert result.cg_images == 4 and "affine" in result.summary()


def test_denoisers_trained_side_by_side_give_the_same_psnr(burst_folder, true_profile):
    """`workers` only changes the wall time: every row, content-equal, one thread and three."""
    kwargs = dict(rows=("upi", "truth", "real"), contents=("scene",), seeds=(0,), steps=20)
    one = burst_check.run_burst_check(burst_folder, true_profile, workers=1, **kwargs)
    three = burst_check.run_burst_check(burst_folder, true_profile, workers=3, **kwargs)
    assert one.psnr == three.psnr and one.psnr_uncorrected == three.psnr_uncorrected
    assert set(one.psnr) == {("upi", "scene"), ("truth", "scene"), ("real", "scene")}
