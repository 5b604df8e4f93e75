"""Conformance corpus, colour part of issue 8: DNGs written with tifffile in the tag layouts real
cameras use (illuminants in either order, DNG 1.6 three illuminants with IlluminantData, one matrix
with no CalibrationIlluminant) go through read -> fit -> profile JSON -> convert -> DNG, and the
written DNG, rendered by an independent DNG colour model (colour_hdri for two illuminants, the
SDK restated in `conformance_colour` for one and three), gives back the input colours within the
round-trip bound (mean dE2000 <= 0.3) for whites between the calibration illuminants and beyond."""

from __future__ import annotations

import colour
import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("colour_hdri")
pytest.importorskip("rawpy")
import conformance_colour as cc  # noqa: E402
from dng_reference import mean_delta_E_2000, patch_camera_rgb, patch_scene, render_patches_to_XYZ_D65  # noqa: E402

from g2r_jax.colour import conversions as gc  # noqa: E402
from g2r_jax.colour import dng_model as dng  # noqa: E402
from g2r_jax.runtime.x64 import enable_x64  # noqa: E402
from g2r_jax.cli.convert import main as convert_main  # noqa: E402
from g2r_jax.profile.fitting import fit_profile  # noqa: E402
from g2r_jax.io.dng_info import DngError  # noqa: E402
from g2r_jax.io.dng_read import read_dng_info, require_colour_tags  # noqa: E402
from g2r_jax.io.illuminant_data import parse_illuminant_data  # noqa: E402
from g2r_jax.profile.schema import load_profile, profile_to_dict, save_profile  # noqa: E402

A_FIRST = dict(codes=(17, 21), color_matrices=(cc.CM_A, cc.CM_D65), camera_calibrations=(cc.CC_A, cc.CC_D65),
               forward_matrices=(cc.FM_A, cc.FM_D65))
D65_FIRST = dict(codes=(21, 17), color_matrices=(cc.CM_D65, cc.CM_A), camera_calibrations=(cc.CC_D65, cc.CC_A),
                 forward_matrices=(cc.FM_D65, cc.FM_A))
# a DNG 1.6 camera: D65, A and an 'other' illuminant given by IlluminantData (a cool-white-like xy)
OTHER_XY = (0.3780, 0.3760)
TRIPLE = dict(codes=(21, 17, 255), color_matrices=(cc.CM_D65, cc.CM_A, cc.CM_F),
              camera_calibrations=(cc.CC_D65, cc.CC_A, cc.CC_F), forward_matrices=(cc.FM_D65, cc.FM_A, cc.FM_F),
              illuminant_data=(None, None, OTHER_XY))


def _profile(tmp_path, name, layout):
    path = cc.write_colour_dng(tmp_path / f"{name}.dng", **layout)
    info = require_colour_tags(read_dng_info(path))
    profile_path = tmp_path / f"{name}.json"
    save_profile(fit_profile([info], name="conformance"), profile_path)
    return profile_path


def _convert(tmp_path, profile_path, neutral, tag):
    folder, codes, boxes = patch_scene(tmp_path)
    csv = tmp_path / f"ill_{tag}.csv"
    csv.write_text(f"r_over_g,g,b_over_g\n{neutral[0]:.9f},1,{neutral[2]:.9f}\n")
    out = tmp_path / f"out_{tag}"
    assert convert_main([str(folder), "--profile", str(profile_path), "-o", str(out), "--no-noise",
                         "--no-effects", "--illuminants", str(csv), "--no-progress"]) == 0
    return out / "patches.dng", codes, boxes


def _delta_E(camera_rgb, codes, XYZ_out):
    linear = colour.models.eotf_sRGB(codes / 255.0)
    XYZ_in = linear @ np.asarray(gc.MATRIX_SRGB_TO_XYZ).T
    unclipped = (linear.max(axis=1) < 0.8) & (camera_rgb.max(axis=1) < 0.95)
    assert unclipped.sum() >= 20
    return mean_delta_E_2000(XYZ_out[unclipped], XYZ_in[unclipped])[0]


def _reference_for(info):
    whites = [None if d is None else tuple(d) for d in (info.illuminant_data or [None] * len(info.color_matrices))]
    whites = [w if w is not None else cc.SDK_WHITE.get(c) for w, c in zip(whites, info.calibration_illuminants)]
    return cc.Reference(info.calibration_illuminants, info.color_matrices, info.camera_calibrations,
                        info.forward_matrices, whites, info.analog_balance if info.analog_balance is not None else (1, 1, 1))


# ----------------------------------------------------------------------------- illuminant order

def test_both_tag_orders_give_the_same_profile_and_the_same_dng(tmp_path):
    """Issue 8: a D65-first phone DNG and an A-first DNG with the same sets give one model: the same
    JSON colour section, the same white for neutral (0.9, 1, 0.35), byte-identical output DNGs."""
    paths = {name: _profile(tmp_path, name, layout) for name, layout in (("a_first", A_FIRST), ("d65_first", D65_FIRST))}
    documents = {name: profile_to_dict(load_profile(p))["colour"] for name, p in paths.items()}
    assert documents["a_first"] == documents["d65_first"]
    assert documents["a_first"]["calibration_illuminants"] == [17, 21]
    np.testing.assert_allclose(documents["a_first"]["color_matrices"][0], cc.CM_A, atol=1e-6)
    np.testing.assert_allclose(documents["a_first"]["forward_matrices"][1], cc.FM_D65, atol=1e-6)
    reference = cc.Reference((21, 17), (cc.CM_D65, cc.CM_A), (cc.CC_D65, cc.CC_A), (cc.FM_D65, cc.FM_A))
    expected = reference.neutral_to_xy(np.array([0.9, 1.0, 0.35]))
    with enable_x64():
        for p in paths.values():
            xy, ok = dng.camera_neutral_to_xy(jnp.asarray([0.9, 1.0, 0.35]), load_profile(p, dtype=np.float64).colour)
            assert bool(ok)
            np.testing.assert_allclose(np.asarray(xy), expected, atol=1e-6)
    neutral = reference.xyz_to_camera(np.array([0.40, 0.39])) @ colour.xy_to_XYZ([0.40, 0.39])
    neutral = neutral / neutral[1]
    outputs = [_convert(tmp_path, p, neutral, name)[0].read_bytes() for name, p in paths.items()]
    assert outputs[0] == outputs[1]


SLOW = pytest.mark.slow


@pytest.mark.parametrize("layout, cct", [("d65_first", 2300), ("d65_first", 4000), ("d65_first", 8500),
                                         pytest.param("a_first", 2300, marks=SLOW), ("a_first", 4000),
                                         pytest.param("a_first", 8500, marks=SLOW)])
def test_two_illuminants_round_trip_through_colour_hdri(tmp_path, layout, cct):
    """Whites below A, between A and D65, and beyond D65; colour_hdri renders the written DNG."""
    profile_path = _profile(tmp_path, layout, A_FIRST if layout == "a_first" else D65_FIRST)
    reference = cc.Reference((17, 21), (cc.CM_A, cc.CM_D65), (cc.CC_A, cc.CC_D65), (cc.FM_A, cc.FM_D65))
    xy = gc.CCT_to_xy(cct)[0]
    neutral = reference.xyz_to_camera(xy) @ colour.xy_to_XYZ(xy)
    dng_path, codes, boxes = _convert(tmp_path, profile_path, neutral / neutral[1], cct)
    info = read_dng_info(dng_path)
    assert info.calibration_illuminants == (17, 21)
    np.testing.assert_allclose(info.color_matrices[0], cc.CM_A, atol=1e-6)
    np.testing.assert_allclose(info.forward_matrices[0], cc.FM_A, atol=1e-6)
    np.testing.assert_allclose(info.camera_calibrations[1], cc.CC_D65, atol=1e-6)
    camera_rgb = patch_camera_rgb(dng_path, boxes)
    delta_E = _delta_E(camera_rgb, codes, render_patches_to_XYZ_D65(camera_rgb, info))
    assert delta_E <= 0.3, f"mean dE2000 {delta_E:.3f} at {cct} K ({layout})"


# ----------------------------------------------------------------------------- three illuminants

def test_triple_weights_and_temperature_match_the_sdk_restated():
    rng = np.random.default_rng(3)
    whites = [cc.SDK_WHITE[21], cc.SDK_WHITE[17], OTHER_XY]
    xys = np.column_stack([rng.uniform(0.28, 0.48, 60), rng.uniform(0.29, 0.43, 60)])
    with enable_x64():
        temperature, tint = (np.asarray(a) for a in jax.jit(gc.xy_to_CCT_tint)(jnp.asarray(xys)))
        weights = np.asarray(jax.jit(jax.vmap(lambda xy: dng.triple_illuminant_weights(xy, jnp.asarray(whites))))(jnp.asarray(xys)))
    reference = np.array([cc.sdk_temperature_tint(xy) for xy in xys])
    np.testing.assert_allclose(temperature, reference[:, 0], rtol=1e-9)
    np.testing.assert_allclose(tint, reference[:, 1], atol=1e-6)
    np.testing.assert_allclose(weights, [cc.sdk_triple_weights(xy, whites) for xy in xys], atol=1e-9)


def test_triple_neutral_to_xy_matches_the_reference_iteration(tmp_path):
    path = cc.write_colour_dng(tmp_path / "t.dng", **TRIPLE)
    info = read_dng_info(path)
    assert info.calibration_illuminants == (21, 17, 255) and info.illuminant_data[2] == pytest.approx(OTHER_XY)
    reference = _reference_for(info)
    with enable_x64():
        model = fit_profile([info], dtype=np.float64).colour
        assert model.calibration_illuminants == (17, 255, 21) and model.is_triple
        for xy in [(0.47, 0.41), (0.4476, 0.4074), (0.40, 0.39), (0.38, 0.375), (0.36, 0.38), (0.345, 0.35),
                   (0.3127, 0.329), (0.30, 0.31), (0.28, 0.29), (0.37, 0.34)]:
            neutral = reference.xyz_to_camera(np.asarray(xy)) @ colour.xy_to_XYZ(xy)
            got, converged = dng.camera_neutral_to_xy(jnp.asarray(neutral / neutral[1]), model)
            assert bool(converged)
            np.testing.assert_allclose(np.asarray(got), reference.neutral_to_xy(neutral), atol=1e-9)
            np.testing.assert_allclose(np.asarray(got), xy, atol=1e-9)   # the white it came from
            np.testing.assert_allclose(np.asarray(dng.matrix_camera_to_XYZ_D50(got, model)),
                                       reference.camera_to_XYZ_D50(np.asarray(got)), atol=1e-9)


def test_triple_neutral_to_xy_converges_over_a_wide_range_in_float32():
    """Whites from deep tungsten to blue sky and well off the locus: the 2-D solve converges and
    returns the white the neutral came from (sampling runs in float32)."""
    rng = np.random.default_rng(0)
    xys = np.column_stack([rng.uniform(0.22, 0.55, 200), rng.uniform(0.22, 0.45, 200)])
    reference = cc.Reference(TRIPLE["codes"], TRIPLE["color_matrices"], TRIPLE["camera_calibrations"],
                             TRIPLE["forward_matrices"], [cc.SDK_WHITE[21], cc.SDK_WHITE[17], OTHER_XY])
    neutrals = np.array([reference.xyz_to_camera(xy) @ colour.xy_to_XYZ(xy) for xy in xys])
    model = dng.DngColourModel.from_tags(TRIPLE["codes"], TRIPLE["color_matrices"], TRIPLE["camera_calibrations"],
                                         TRIPLE["forward_matrices"], illuminant_data=TRIPLE["illuminant_data"])
    got, converged = dng.camera_neutrals_to_xy(jnp.asarray(neutrals / neutrals[:, 1:2], jnp.float32), model, throw=False)
    assert bool(np.all(np.asarray(converged)))
    np.testing.assert_allclose(np.asarray(got), xys, atol=1e-5)


@pytest.mark.parametrize("xy", [(0.47, 0.41), pytest.param((0.38, 0.38), marks=SLOW), (0.345, 0.352),
                                pytest.param((0.29, 0.30), marks=SLOW)],
                         ids=["below_A", "near_other", "between", "beyond_D65"])
def test_three_illuminants_round_trip_through_the_sdk_reference(tmp_path, xy):
    profile_path = _profile(tmp_path, "triple", TRIPLE)
    document = profile_to_dict(load_profile(profile_path))["colour"]
    assert document["calibration_illuminants"] == [17, 255, 21]
    assert document["illuminant_data"][1] == pytest.approx(list(OTHER_XY), abs=1e-6)
    reference = cc.Reference(*(TRIPLE[k] for k in ("codes", "color_matrices", "camera_calibrations",
                                                   "forward_matrices")), [cc.SDK_WHITE[21], cc.SDK_WHITE[17], OTHER_XY])
    neutral = reference.xyz_to_camera(np.asarray(xy)) @ colour.xy_to_XYZ(xy)
    dng_path, codes, boxes = _convert(tmp_path, profile_path, neutral / neutral[1], "t")
    info = read_dng_info(dng_path)
    assert info.dng_version == (1, 6, 0, 0) and info.calibration_illuminants == (17, 255, 21)
    assert info.illuminant_data[1] == pytest.approx(OTHER_XY, abs=1e-6)
    np.testing.assert_allclose(info.color_matrices[1], cc.CM_F, atol=1e-6)
    camera_rgb = patch_camera_rgb(dng_path, boxes)
    delta_E = _delta_E(camera_rgb, codes, _reference_for(info).render_to_XYZ_D65(camera_rgb, info.as_shot_neutral))
    assert delta_E <= 0.3, f"mean dE2000 {delta_E:.3f} at xy {xy}"


def test_illuminant_data_spectrum_is_read_as_its_white():
    """IlluminantData type 1 (spectrum): D65's spectral distribution gives D65's xy."""
    sd = colour.SDS_ILLUMINANTS["D65"].copy().align(colour.SpectralShape(360, 830, 5))
    blob = cc.illuminant_data_spectrum_bytes(360, 5, sd.values)
    xy = parse_illuminant_data(blob, "<")
    np.testing.assert_allclose(xy, colour.CCS_ILLUMINANTS[cc.OBSERVER]["D65"], atol=2e-4)
    with pytest.raises(ValueError, match="unknown type"):
        parse_illuminant_data(b"\x07\x00" + bytes(16), "<")


def test_other_illuminant_without_data_is_refused_in_one_line(tmp_path):
    layout = dict(TRIPLE, illuminant_data=None)
    path = cc.write_colour_dng(tmp_path / "no_data.dng", **layout)
    with pytest.raises(DngError, match=r"CalibrationIlluminant3 is 255 \(other\) but IlluminantData3 is missing"):
        require_colour_tags(read_dng_info(path))


# ----------------------------------------------------------------------------- one matrix, no illuminant

def test_single_matrix_without_calibration_illuminant_round_trips(tmp_path):
    """ColorMatrix1 alone, CalibrationIlluminant1 absent (spec default 0, unknown): accepted."""
    layout = dict(codes=None, color_matrices=(cc.CM_D65,), forward_matrices=(cc.FM_D65,))
    profile_path = _profile(tmp_path, "single", layout)
    assert profile_to_dict(load_profile(profile_path))["colour"]["calibration_illuminants"] == [0]
    reference = cc.Reference((0,), (cc.CM_D65,), (), (cc.FM_D65,))
    xy = gc.CCT_to_xy(3500)[0]
    neutral = reference.xyz_to_camera(xy) @ colour.xy_to_XYZ(xy)
    dng_path, codes, boxes = _convert(tmp_path, profile_path, neutral / neutral[1], "single")
    info = read_dng_info(dng_path)
    assert info.calibration_illuminants == (0,) and len(info.color_matrices) == 1
    camera_rgb = patch_camera_rgb(dng_path, boxes)
    delta_E = _delta_E(camera_rgb, codes, reference.render_to_XYZ_D65(camera_rgb, info.as_shot_neutral))
    assert delta_E <= 0.3, f"mean dE2000 {delta_E:.3f}"


# ----------------------------------------------------------------------------- real files

@pytest.mark.data
def test_real_files_keep_each_matrix_with_its_illuminant_in_either_order(shared_data):
    """The real DNGs' colour tags, read as stored and with their sets reversed (as a D65-first
    phone writes them), give one model whose tags pair every code with the file's own matrices."""
    checked = 0
    for path in sorted((shared_data / "dng").glob("*.dng")):
        info = read_dng_info(path)
        if len(info.color_matrices) < 2:
            continue
        sets = list(zip(info.calibration_illuminants, info.color_matrices,
                        info.camera_calibrations or [np.eye(3)] * len(info.color_matrices),
                        info.forward_matrices or [None] * len(info.color_matrices)))
        models = []
        for order in (sets, sets[::-1]):
            codes, cms, ccs, fms = zip(*order)
            models.append(dng.DngColourModel.from_tags(codes, cms, ccs, () if fms[0] is None else fms, dtype=np.float64))
        tags = [m.dng_tags() for m in models]
        assert tags[0]["calibration_illuminants"] == tags[1]["calibration_illuminants"]
        for code, matrix in zip(tags[0]["calibration_illuminants"], tags[0]["color_matrices"]):
            stored = info.color_matrices[info.calibration_illuminants.index(code)]
            np.testing.assert_allclose(matrix, stored, atol=1e-7, err_msg=f"{path.name}: code {code}")
        for a, b in zip(tags[0]["color_matrices"], tags[1]["color_matrices"]):
            np.testing.assert_array_equal(a, b)
        checked += 1
    assert checked >= 2


def test_two_illuminants_one_given_by_illuminant_data(tmp_path):
    """D65 and an 'other' (255) illuminant at Standard Light A's xy: interpolated in mired at the
    Robertson CCT of its IlluminantData white; colour_hdri at those temperatures agrees, and the
    written DNG carries the IlluminantData with its matrix."""
    from dng_reference import neutral_to_xy

    layout = dict(codes=(21, 255), color_matrices=(cc.CM_D65, cc.CM_A), illuminant_data=(None, cc.SDK_WHITE[17]))
    info = require_colour_tags(read_dng_info(cc.write_colour_dng(tmp_path / "other.dng", **layout)))
    profile_path = tmp_path / "other.json"
    save_profile(fit_profile([info], name="conformance"), profile_path)
    with enable_x64():
        model = load_profile(profile_path, dtype=np.float64).colour
        assert model.calibration_illuminants == (255, 21)
        cct_other = float(model.calibration_cct[0])
        assert 2850 < cct_other < 2860            # Robertson CCT of (0.4476, 0.4074)
        arguments = (cct_other, 6500.0, cc.CM_A, cc.CM_D65, np.eye(3), np.eye(3), np.ones(3))
        for neutral in ([0.45, 1, 0.75], [0.6, 1, 0.55], [0.9, 1, 0.35]):
            xy, ok = dng.camera_neutral_to_xy(jnp.asarray(neutral, jnp.float64), model)
            assert bool(ok)
            np.testing.assert_allclose(np.asarray(xy), neutral_to_xy(np.asarray(neutral, np.float64), *arguments), atol=1e-9)
    dng_path, _, _ = _convert(tmp_path, profile_path, np.array([0.6, 1.0, 0.55]), "other")
    written = read_dng_info(dng_path)
    assert written.dng_version == (1, 6, 0, 0) and written.calibration_illuminants == (255, 21)
    assert written.illuminant_data[0] == pytest.approx(cc.SDK_WHITE[17], abs=1e-6) and written.illuminant_data[1] is None
    np.testing.assert_allclose(written.color_matrices[0], cc.CM_A, atol=1e-6)
