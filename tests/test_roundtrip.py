"""Acceptance: a DNG written by `g2r-convert --no-noise` for a given illuminant, rendered through
the DNG colour model (colour_hdri), gives back the input colours (mean dE2000 <= 0.3)."""

from __future__ import annotations

import colour
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("colour_hdri")
from dng_reference import mean_delta_E_2000, patch_camera_rgb, patch_scene, render_patches_to_XYZ_D65  # noqa: E402

from g2r_jax.colour import conversions as gc  # noqa: E402
from g2r_jax.colour import dng_model as dng  # noqa: E402
from g2r_jax.runtime.x64 import enable_x64  # noqa: E402
from g2r_jax.cli.convert import main as convert_main  # noqa: E402
from g2r_jax.io.dng_read import read_dng_info  # noqa: E402
from g2r_jax.profile.schema import load_profile, save_profile  # noqa: E402



def neutral_for_cct(profile, cct):
    with enable_x64():
        model = dng.DngColourModel.from_tags(profile.info.calibration_illuminants,
                                             np.asarray(profile.colour.color_matrix[:len(profile.info.calibration_illuminants)], np.float64),
                                             dtype=np.float64)
        return np.asarray(dng.xy_to_camera_neutral(jnp.asarray(gc.CCT_to_xy(cct)[0]), model))


def round_trip_delta_E(tmp_path, profile_path, cct):
    profile = load_profile(profile_path)
    folder, codes, boxes = patch_scene(tmp_path)
    neutral = neutral_for_cct(profile, cct)
    csv = tmp_path / f"ill_{cct}.csv"
    csv.write_text(f"r_over_g,g,b_over_g\n{neutral[0]:.9f},1,{neutral[2]:.9f}\n")
    out = tmp_path / f"out_{cct}"
    status = convert_main([str(folder), "--profile", str(profile_path), "-o", str(out), "--no-noise",
                           "--illuminants", str(csv), "--no-progress", "--no-content-model"])
    assert status == 0
    dng_path = out / "patches.dng"
    info = read_dng_info(dng_path)
    np.testing.assert_allclose(info.as_shot_neutral, neutral, rtol=1e-5)
    camera_rgb = patch_camera_rgb(dng_path, boxes)
    XYZ_out = render_patches_to_XYZ_D65(camera_rgb, info)
    linear = colour.models.eotf_sRGB(codes / 255.0)
    XYZ_in = linear @ np.asarray(gc.MATRIX_SRGB_TO_XYZ).T
    # unclipped: below the highlight-safe inflection (white patch excluded) and below saturation
    unclipped = (linear.max(axis=1) < 0.8) & (camera_rgb.max(axis=1) < 0.95)
    assert unclipped.sum() >= 20
    delta_E, _ = mean_delta_E_2000(XYZ_out[unclipped], XYZ_in[unclipped])
    return delta_E


@pytest.mark.parametrize("cct", [2900, 4000, 5000, 6500])
def test_round_trip_A_D65_camera(tmp_path, cct):
    """A camera calibrated at Standard Light A / D65 (the shipped Canon 600D profile)."""
    delta_E = round_trip_delta_E(tmp_path, "profiles/Canon600D.json", cct)
    assert delta_E <= 0.3, f"mean dE2000 {delta_E:.3f} at {cct} K"


@pytest.mark.data
@pytest.mark.parametrize("cct", [2900, 4000, 5000, 6500])
def test_round_trip_real_gopro_tungsten_D50(tmp_path, shared_data, cct):
    """The real GoPro HERO6 DNG (Tungsten / D50 calibration), profile fitted from its tags."""
    from g2r_jax.profile.fitting import fit_profile

    info = read_dng_info(shared_data / "dng" / "gopro_hero6_GOPR0024.dng")
    profile_path = tmp_path / "gopro.json"
    save_profile(fit_profile([info], name="gopro"), profile_path)
    delta_E = round_trip_delta_E(tmp_path, profile_path, cct)
    assert delta_E <= 0.3, f"mean dE2000 {delta_E:.3f} at {cct} K"


def test_published_recipe_is_measurably_less_exact(tmp_path):
    """The published approximation (row-normalised matrices, 2500 K for A, gamma 2.2) does not
    invert a DNG renderer; this documents by how much, and guards that the option differs."""
    profile = load_profile("profiles/Canon600D.json")
    folder, codes, boxes = patch_scene(tmp_path)
    neutral = neutral_for_cct(profile, 4000)
    csv = tmp_path / "ill.csv"
    csv.write_text(f"r_over_g,g,b_over_g\n{neutral[0]:.9f},1,{neutral[2]:.9f}\n")
    out = tmp_path / "out"
    assert convert_main([str(folder), "--profile", "profiles/Canon600D.json", "-o", str(out), "--no-noise",
                         "--illuminants", str(csv), "--recipe", "published", "--no-progress"]) == 0
    info = read_dng_info(out / "patches.dng")
    camera_rgb = patch_camera_rgb(out / "patches.dng", boxes)
    linear = colour.models.eotf_sRGB(codes / 255.0)
    XYZ_in = linear @ np.asarray(gc.MATRIX_SRGB_TO_XYZ).T
    keep = linear.max(axis=1) < 0.8
    delta_E, _ = mean_delta_E_2000(render_patches_to_XYZ_D65(camera_rgb, info)[keep], XYZ_in[keep])
    assert delta_E > 1.0
