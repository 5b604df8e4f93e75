"""Shared helpers of the audit tests: measured sets with hidden effects, built from the project's
own simulation (g2r_jax.audit.synthetic)."""

from __future__ import annotations

import numpy as np

from g2r_jax.audit import scenes, simulate, synthetic

N_FILES, HEIGHT, WIDTH = 24, 200, 300


def measured_set(profile, seed: int, n: int = N_FILES, height: int = HEIGHT, width: int = WIDTH):
    """n files of the 'true camera' `profile`, from scenes the audit never sees (own seeds)."""
    return simulate.simulate(profile, scenes.scene_set(n, 10_000 + seed, height, width), 50_000 + seed)


def dark_frames(profile, seed: int, n: int = 3, height: int = HEIGHT, width: int = WIDTH):
    """n dark frames of the 'true camera' `profile` (a black scene: lens capped), the black-level
    evidence a measured set needs (the audit does not read a pedestal from scene content)."""
    return simulate.simulate(profile, np.zeros((n, height, width, 3), np.float32), 70_000 + seed)


def hidden_effect(cause: str, rng, base=None):
    """(true profile, magnitude) with `cause` injected at a random modest magnitude."""
    base = base if base is not None else synthetic.demo_profile()
    magnitude = synthetic.random_magnitude(cause, rng)
    return synthetic.inject(base, cause, height=HEIGHT, width=WIDTH, **magnitude), magnitude


def significant(report):
    return [f for f in report["findings"] if f["significant"]]


def assert_parameter_close(cause, params, magnitude, truth_profile, shading_tolerance=0.06):
    """The fitted parameter of `cause` is close to the injected one. `shading_tolerance` bounds the
    corner gains' error; 0.06 suits 200x300 files, smaller files need more (test_audit_profiles)."""
    if cause == "black_level":
        assert abs(params["offset_fraction"] - magnitude["offset"]) < 0.15 * magnitude["offset"] + 5e-4
    elif cause == "white_level":
        assert abs(params["clip_level"] - magnitude["clip"]) < 0.005
    elif cause == "green_imbalance":
        assert abs(params["green2_over_green1"] - magnitude["ratio"]) < 0.2 * abs(magnitude["ratio"] - 1)
    elif cause == "lens_shading":
        truth = 1 + np.asarray(truth_profile.effects.shading).sum(1)
        assert np.all(np.abs(np.asarray(params["corner_gain"]) - truth) < shading_tolerance), (params["corner_gain"], truth)
    elif cause == "noise_model":
        assert np.all(np.abs(np.asarray(params["shot_scale"]) / magnitude["scale"] - 1) < 0.2)
        assert np.all(np.abs(np.asarray(params["read_scale"]) / magnitude["scale"] - 1) < 0.35)
    elif cause == "banding":
        key = "row_noise_std" if magnitude["axis"] == "row" else "column_noise_std"
        other = "column_noise_std" if key == "row_noise_std" else "row_noise_std"
        assert abs(params[key] - magnitude["std"]) < 0.2 * magnitude["std"]
        assert params[other] < 0.3 * magnitude["std"]
    elif cause == "exposure_distribution":
        assert abs(params["log2_mean"] - magnitude["stops"]) < 0.25
    elif cause == "defective_pixels":
        truth = set(zip(np.asarray(truth_profile.effects.defect_rows).tolist(),
                        np.asarray(truth_profile.effects.defect_cols).tolist()))
        found = {(r, c) for r, c, _ in params["defects"]}
        assert found <= truth, found - truth
        assert len(found) >= 0.6 * len(truth)
    elif cause == "illuminant_distribution":
        assert len(params["weights"]) >= 2
