"""The DNG colour model against colour_hdri (Adobe DNG SDK colour processing) to 1e-6."""

import zlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

colour_hdri = pytest.importorskip("colour_hdri")
from colour_hdri.models import dng as reference  # noqa: E402

from g2r_jax.colour import dng_model as dng  # noqa: E402
from dng_reference import NotConverged, neutral_to_xy  # noqa: E402
from g2r_jax.runtime.x64 import enable_x64  # noqa: E402

I3 = np.eye(3)


@pytest.fixture(autouse=True)
def x64():
    with enable_x64():
        yield


def random_camera(rng, *, forward: bool, calibration: bool, codes=(17, 21)):
    """A plausible random camera: perturbed real-looking XYZ->camera matrices."""
    base = np.array([[0.67, -0.12, -0.05], [-0.65, 1.42, 0.27], [-0.09, 0.12, 0.75]])
    cm = [base + rng.normal(0, 0.02, (3, 3)) for _ in codes]
    cc = [I3 + rng.normal(0, 0.02, (3, 3)) for _ in codes] if calibration else []
    fm = []
    if forward:
        fm = [np.array([[0.79, 0.15, 0.02], [0.29, 0.87, -0.16], [0.02, -0.12, 0.93]]) + rng.normal(0, 0.02, (3, 3))
              for _ in codes]
    ab = rng.uniform(0.9, 1.1, 3) if calibration else np.ones(3)
    return cm, cc, fm, ab


def reference_args(codes, cm, cc, fm, ab):
    """colour_hdri's argument list; a missing second calibration is passed as identity (its convention)."""
    ccts = [dng.calibration_illuminant_cct(c) for c in codes]
    order = np.argsort(ccts)
    pick = lambda ms: [ms[i] for i in order] if ms else [I3, I3]
    cm_, cc_, fm_ = pick(cm), pick(cc), pick(fm)
    ccts = sorted(ccts)
    if len(codes) == 1:
        cm_, cc_, fm_ = [cm[0], I3], [cc[0] if cc else I3, I3], [fm[0] if fm else I3, I3]
        ccts = [ccts[0], ccts[0]]
    return ccts, cm_, cc_, fm_, ab


CASES = [
    dict(forward=False, calibration=False, codes=(17, 21)),
    dict(forward=True, calibration=False, codes=(17, 21)),
    dict(forward=False, calibration=True, codes=(21, 17)),
    dict(forward=True, calibration=True, codes=(3, 23)),
    dict(forward=False, calibration=False, codes=(14, 20)),
]


@pytest.mark.parametrize("case", CASES)
def test_matrices_and_white_point_agree_with_colour_hdri(case):
    rng = np.random.default_rng(zlib.crc32(str(case).encode()))
    agreements = []
    for _ in range(8):
        cm, cc, fm, ab = random_camera(rng, forward=case["forward"], calibration=case["calibration"], codes=case["codes"])
        model = dng.DngColourModel.from_tags(case["codes"], cm, cc, fm, ab, dtype=np.float64)
        ccts, cm_, cc_, fm_, ab_ = reference_args(case["codes"], cm, cc, fm, ab)
        # whites from 2000 K to 12000 K: well outside the calibration range on both sides
        for cct in rng.uniform(2000, 12000, 4):
            import colour
            xy = colour.temperature.CCT_to_xy_Kang2002(cct) + rng.normal(0, 0.003, 2)
            np.testing.assert_allclose(dng.matrix_XYZ_to_camera(jnp.asarray(xy), model),
                                       reference.matrix_XYZ_to_camera_space(xy, *ccts, *cm_, *cc_, ab_), atol=1e-6)
            np.testing.assert_allclose(dng.matrix_camera_to_XYZ_D50(jnp.asarray(xy), model),
                                       reference.matrix_camera_space_to_XYZ(xy, *ccts, *cm_, *cc_, ab_, *fm_), atol=1e-6)
            neutral = reference.xy_to_camera_neutral(xy, *ccts, *cm_, *cc_, ab_)
            np.testing.assert_allclose(dng.xy_to_camera_neutral(jnp.asarray(xy), model), neutral, atol=1e-6)
            got_xy, converged = dng.camera_neutral_to_xy(jnp.asarray(neutral), model)
            assert bool(converged)
            # always: colour_hdri maps our white point back to the neutral (a true fixed point)
            np.testing.assert_allclose(reference.xy_to_camera_neutral(np.asarray(got_xy), *ccts, *cm_, *cc_, ab_),
                                       neutral, atol=1e-9)
            try:   # and where the specification's iteration converges, it lands on the same xy
                np.testing.assert_allclose(got_xy, neutral_to_xy(neutral, *ccts, *cm_, *cc_, ab_), atol=1e-6)
                agreements.append(1)
            except NotConverged:
                agreements.append(0)
    assert sum(agreements) >= len(agreements) // 2


def test_single_calibrated_matrix_agrees_with_colour_hdri():
    rng = np.random.default_rng(7)
    cm, _, _, _ = random_camera(rng, forward=False, calibration=False, codes=(21,))
    model = dng.DngColourModel.from_tags((21,), cm, dtype=np.float64)
    for xy in ([0.45, 0.41], [0.31, 0.33], [0.28, 0.29]):
        xy = np.array(xy)
        expected = reference.matrix_camera_space_to_XYZ(xy, 6500, 6500, cm[0], I3, I3, I3, np.ones(3), I3, I3)
        np.testing.assert_allclose(dng.matrix_camera_to_XYZ_D50(jnp.asarray(xy), model), expected, atol=1e-6)


def test_vmapped_white_points_match_one_by_one():
    rng = np.random.default_rng(3)
    cm, cc, fm, ab = random_camera(rng, forward=True, calibration=True)
    model = dng.DngColourModel.from_tags((17, 21), cm, cc, fm, ab, dtype=np.float64)
    neutrals = np.stack([np.array([rng.uniform(0.3, 1.1), 1.0, rng.uniform(0.3, 1.0)]) for _ in range(64)])
    xy, converged = dng.camera_neutrals_to_xy(neutrals, model)
    assert bool(np.all(converged))
    ccts, cm_, cc_, fm_, ab_ = reference_args((17, 21), cm, cc, fm, ab)
    for n, got in zip(neutrals[:8], np.asarray(xy[:8])):
        np.testing.assert_allclose(got, neutral_to_xy(n, *ccts, *cm_, *cc_, ab_), atol=1e-6)


def test_interpolation_weight_is_clamped():
    model = dng.DngColourModel.from_tags((17, 21), [np.eye(3), 2 * np.eye(3)], dtype=np.float64)
    assert float(dng.interpolation_weight(2000.0, model)) == 1.0
    assert float(dng.interpolation_weight(10000.0, model)) == 0.0
    assert 0 < float(dng.interpolation_weight(4000.0, model)) < 1


def test_every_exif_light_source_code_with_a_temperature_is_supported():
    for code, cct in dng.CALIBRATION_ILLUMINANT_CCT.items():
        assert 2000 < dng.calibration_illuminant_cct(code) == cct < 8000
    with pytest.raises(ValueError, match="255"):
        dng.calibration_illuminant_cct(255)


def test_white_point_is_a_true_fixed_point_even_for_extreme_neutrals():
    """Where the plain iteration would oscillate, Newton still returns xy with neutral(xy) = neutral."""
    rng = np.random.default_rng(11)
    for _ in range(6):
        cm, cc, fm, ab = random_camera(rng, forward=False, calibration=True)
        cm = [m + rng.normal(0, 0.05, (3, 3)) for m in cm]
        model = dng.DngColourModel.from_tags((17, 21), cm, cc, fm, ab, dtype=np.float64)
        for neutral in ([0.25, 1.0, 1.1], [1.2, 1.0, 0.2], [0.6, 1.0, 0.6]):
            xy, converged = dng.camera_neutral_to_xy(jnp.asarray(neutral), model)
            assert bool(converged)
            np.testing.assert_allclose(dng.xy_to_camera_neutral(xy, model), neutral, atol=1e-9)
