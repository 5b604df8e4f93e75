"""White points up to the spectrum locus: every light is accepted, what no light can be is refused."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from g2r_jax.cli import fit_profile as cli
from g2r_jax.colour.spectrum_locus import LOCUS_MARGIN, distance_outside_locus, is_light_chromaticity
from g2r_jax.io.dng_info import DngError, DngInfo
from g2r_jax.io.dng_write import write_dng
from g2r_jax.profile.fitting import check_file_colour

# the Samsung Galaxy S20 FE's D65 ColorMatrix (its shipped profile, profiles/s20fe_night.json)
S20FE_D65 = np.array([[0.6787109375, -0.1640625, -0.0810546875],
                      [-0.3935546875, 1.193359375, 0.166015625],
                      [-0.1015625, 0.2685546875, 0.4541015625]])
SODIUM_NEUTRAL = np.array([1.14443886, 1.0, 0.18312833])   # a real S20 FE night lamp (low-pressure sodium)


def s20fe_info(neutral, path="") -> DngInfo:
    return DngInfo(path=path, width=64, height=48, cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, 64.0),
                   white_level=1023.0, unique_camera_model="Samsung Galaxy S20 FE", make="Samsung",
                   model="Galaxy S20 FE", calibration_illuminants=(21,), color_matrices=(S20FE_D65,),
                   as_shot_neutral=np.asarray(neutral, np.float64), noise_profile=np.array([[1.5e-4, 2e-6]]),
                   iso=100.0, exposure_time=0.01)


@pytest.mark.parametrize("xy", [(0.3127, 0.3290), (0.4476, 0.4074), (0.5752, 0.4242), (0.7347, 0.2653),
                                (0.1741, 0.0050), (0.0082, 0.5384), (0.58026, 0.43012)])
def test_lights_are_accepted(xy):
    """D65, A, the low-pressure sodium line, the locus ends and the S20 FE's sodium lamp as solved."""
    assert is_light_chromaticity(xy)


@pytest.mark.parametrize("xy", [(0.8, 0.4), (0.3, 0.9), (0.4, -0.01), (-0.01, 0.5), (0.3, 0.0),
                                (np.nan, 0.3), (np.inf, 0.3)])
def test_what_no_light_can_be_is_refused(xy):
    assert not is_light_chromaticity(xy)


def test_distance_is_zero_on_the_locus_and_grows_outside():
    assert abs(distance_outside_locus((0.7347, 0.2653))) < 1e-3
    assert distance_outside_locus((0.3127, 0.3290)) < -0.1
    assert distance_outside_locus((0.6, 0.39)) < 0 < distance_outside_locus((0.65, 0.39)) < LOCUS_MARGIN
    assert distance_outside_locus((0.8, 0.4)) > LOCUS_MARGIN


def test_sodium_lamp_file_is_accepted_and_an_impossible_one_refused():
    """x + y > 1 (the sodium lamp through the S20 FE matrix: 1.010) is a light; a neutral that solves
    far beyond the locus is not, and the error names the file and how far out it lies."""
    assert check_file_colour(s20fe_info(SODIUM_NEUTRAL, "sodium.dng")).path == "sodium.dng"
    with pytest.raises(DngError, match=r"impossible\.dng: .*outside the spectrum locus"):
        check_file_colour(s20fe_info([0.1, 1.0, 0.1], "impossible.dng"))   # xy (0.33, 0.94)
    with pytest.raises(DngError, match=r"negative\.dng: .*xy \(0\.135, -0\.014\) has a coordinate <= 0"):
        check_file_colour(s20fe_info([0.3, 1.0, 5.0], "negative.dng"))


@pytest.mark.data
@pytest.mark.slow
def test_the_45_s20fe_night_files_fit_with_exit_0(shared_data, tmp_path, capsys):
    """The 45 real S20 FE night illuminants as AsShotNeutral of 45 small DNGs (our writer): all kept."""
    with open(shared_data / "illuminants" / "s20fe_night_graycard_45.csv", newline="") as handle:
        neutrals = [[float(r["r_over_g"]), float(r["g"]), float(r["b_over_g"])] for r in csv.DictReader(handle)]
    assert len(neutrals) == 45
    matrix = np.reshape(json.loads((shared_data / "cameras" / "color_matrices.json").read_text())
                        ["Samsung Galaxy S20 FE (main camera)"]["ColorMatrix_D65_tag21"], (3, 3))
    np.testing.assert_allclose(matrix, S20FE_D65, atol=1e-6)
    folder = tmp_path / "night"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for k, neutral in enumerate(neutrals):
        mosaic = (64 + rng.integers(0, 600, (48, 64))).astype(np.uint16)
        write_dng(folder / f"night_{k:02d}.dng", mosaic, s20fe_info(neutral))
    out = tmp_path / "night.json"
    assert cli.main([str(folder), "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "45 file(s); 0 failed" in captured.out
    assert "error" not in captured.err
    hull = np.asarray(json.loads(out.read_text())["illuminants"]["hull"])
    # the sodium lamp's chromaticity (r/g, b/g) lies inside the fitted illuminant hull
    point = np.array([SODIUM_NEUTRAL[0], SODIUM_NEUTRAL[2]])
    assert np.all(hull[:, :2] @ point + hull[:, 2] <= 1e-6)
