"""A folder of several cameras: the camera with complete, decodable files is fitted, whatever the file
order, and the command says which camera it chose, why, and which files it left out."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from g2r_jax.cli import fit_profile as cli
from g2r_jax.io.dng_info import DngInfo
from g2r_jax.io.dng_write import write_dng
from g2r_jax.profile.fitting import choose_camera

CM_D65 = np.array([[0.6722, -0.0635, -0.0963], [-0.4287, 1.2460, 0.2028], [-0.0908, 0.2162, 0.5668]])
CM_A = np.array([[0.7861, -0.2131, -0.0346], [-0.3938, 1.1473, 0.2869], [-0.0377, 0.1439, 0.6588]])


def camera_info(model: str, path: str = "", **changes) -> DngInfo:
    info = DngInfo(path=path, cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, 64.0), white_level=4095.0,
                   unique_camera_model=model, make="G2R", model=model, calibration_illuminants=(17, 21),
                   color_matrices=(CM_A, CM_D65), as_shot_neutral=np.array([0.5, 1.0, 0.6]),
                   noise_profile=np.array([[2e-4, 1e-6]]), iso=200.0, exposure_time=0.01)
    return dataclasses.replace(info, **changes)


def test_decodable_files_win_over_more_header_only_files():
    header_only = [camera_info("A header only", f"a{k}.dng", pixel_data_problem="pixel data incomplete")
                   for k in range(3)]
    complete = [camera_info("B complete", "b.dng")]
    for infos in (header_only + complete, complete + header_only):
        kept, left_out, line = choose_camera(infos)
        assert [i.path for i in kept] == ["b.dng"]
        assert [i.path for k, members in left_out.items() for i in members] == ["a0.dng", "a1.dng", "a2.dng"]
        assert "fitting B complete (1 file(s), 1 with decodable pixels): the most files with decodable pixels" in line
        assert "left out: A header only (3 file(s), 0 with decodable pixels)" in line


def test_a_tie_is_settled_by_name_not_by_file_order():
    one, other = camera_info("Camera Z", "z.dng"), camera_info("Camera M", "m.dng")
    for infos in ([one, other], [other, one]):
        kept, _, line = choose_camera(infos)
        assert [i.path for i in kept] == ["m.dng"] and "settled by camera name" in line
    more = [camera_info("Camera Z", f"z{k}.dng") for k in range(2)] + [other]
    assert [i.path for i in choose_camera(more)[0]] == ["z0.dng", "z1.dng"]


def test_one_camera_needs_no_choice():
    infos = [camera_info("Only", f"o{k}.dng") for k in range(2)]
    assert choose_camera(infos) == (infos, {}, None)


def test_folder_with_a_header_only_camera_first(tmp_path, capsys):
    """The header-only file sorts first and its camera has as many files: the complete one is fitted."""
    rng = np.random.default_rng(0)
    mosaic = (64 + rng.integers(0, 2000, (48, 64))).astype(np.uint16)
    write_dng(tmp_path / "b_complete.dng", mosaic, camera_info("B complete"))
    write_dng(tmp_path / "full.dng", mosaic, camera_info("A header only"))
    data = (tmp_path / "full.dng").read_bytes()
    (tmp_path / "full.dng").unlink()
    (tmp_path / "a_header_only.dng").write_bytes(data[:-1000])   # the pixel data cut short, tags intact
    out = tmp_path / "p.json"
    assert cli.main([str(tmp_path), "-o", str(out)]) == 1        # a file was left out: said in the exit code
    assert json.loads(out.read_text())["camera"]["unique_camera_model"] == "B complete"
    err = capsys.readouterr().err
    assert "fitting B complete (1 file(s), 1 with decodable pixels)" in err
    assert "a_header_only.dng: left out: a different camera (A header only" in err


@pytest.mark.data
def test_shared_dng_folder_fits_the_gopro(shared_data, tmp_path, capsys):
    """The 350D is header-only and the 6D is LinearRaw: the GoPro frame is fitted, both are named."""
    out = tmp_path / "p.json"
    assert cli.main([str(shared_data / "dng"), "-o", str(out)]) == 1
    assert json.loads(out.read_text())["camera"]["unique_camera_model"] == "GoPro HERO6 Black"
    err = capsys.readouterr().err
    assert "fitting GoPro HERO6 Black (1 file(s), 1 with decodable pixels)" in err
    assert "canon_350d_header_only.dng: left out: a different camera (Canon EOS 350D" in err
    assert "canon_eos_6d_linear_raw.dng: raw image is LinearRaw" in err
