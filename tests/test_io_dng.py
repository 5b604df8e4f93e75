"""DNG reading and writing: round trips through our reader and LibRaw, real files, bad inputs."""

from __future__ import annotations

import dataclasses
import hashlib
import os
from pathlib import Path

import numpy as np
import pytest
import rawpy
import tifffile

from g2r_jax.io.dng_info import DngError, DngInfo
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels, require_bayer_cfa, require_colour_tags
from g2r_jax.io.dng_write import to_rationals, write_dng, write_dng_bytes

DATA = Path(__file__).parents[1] / ".." / "shared" / "data"
DNG_DIR = DATA / "dng"
needs_data = pytest.mark.skipif(not DNG_DIR.is_dir(), reason="../shared/data absent")

CM_A = np.array([[0.6159, -0.0945, -0.0745], [-0.6846, 1.3563, 0.3684], [-0.0802, 0.1086, 0.7555]])
CM_D65 = np.array([[0.6018, -0.0617, -0.0965], [-0.8645, 1.5881, 0.2975], [-0.153, 0.1719, 0.7642]])
FM_A = np.array([[0.7763, 0.0065, 0.1815], [0.2364, 0.8351, -0.0715], [-0.0059, -0.4228, 1.2538]])
FM_D65 = np.array([[0.7464, 0.1044, 0.1135], [0.2648, 0.9173, -0.182], [0.0113, -0.2154, 1.0292]])
# dcraw/LibRaw's linear sRGB (D65) -> XYZ matrix, used by LibRaw to derive rawpy's color_matrix
XYZ_RGB = np.array([[0.412453, 0.357580, 0.180423], [0.212671, 0.715160, 0.072169],
                    [0.019334, 0.119193, 0.950227]])
PATTERNS = {"RGGB": (0, 1, 1, 2), "BGGR": (2, 1, 1, 0), "GRBG": (1, 0, 2, 1), "GBRG": (1, 2, 0, 1)}


def sha(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def make_info(pattern=(0, 1, 1, 2), **changes) -> DngInfo:
    info = DngInfo(
        make="G2R", model="Synthetic 1", unique_camera_model="G2R Synthetic 1",
        cfa_pattern=pattern, black_level=np.array([64.0, 65.0, 66.0, 67.0]), white_level=1023.0,
        calibration_illuminants=(17, 21), color_matrices=(CM_A, CM_D65),
        camera_calibrations=(np.diag([1.0069, 1.0, 1.0027]), np.diag([1.01, 1.0, 0.99])),
        forward_matrices=(FM_A, FM_D65), analog_balance=np.array([1.0, 1.0, 1.0]),
        as_shot_neutral=np.array([0.522449, 1.0, 0.571429]), baseline_exposure=-0.35,
        noise_profile=np.array([[1.562e-4, 4.88e-8], [1.6e-4, 5e-8], [1.7e-4, 6e-8]]),
        iso=400.0, exposure_time=1 / 60,
        opcode_lists={"OpcodeList2": bytes(range(40)), "OpcodeList3": b"\x00\x00\x00\x00"})
    return dataclasses.replace(info, **changes)


def random_mosaic(shape=(32, 48), high=1024, seed=0) -> np.ndarray:
    # LibRaw refuses images under 22 pixels on a side, hence at least 32x48
    return np.random.default_rng(seed).integers(0, high, shape).astype(np.uint16)


def libraw_rgb_cam(cm: np.ndarray) -> np.ndarray:
    """rawpy's color_matrix as LibRaw derives it from one XYZ->camera matrix (dcraw cam_xyz_coeff)."""
    cam_rgb = cm @ XYZ_RGB
    cam_rgb = cam_rgb / cam_rgb.sum(axis=1, keepdims=True)
    return np.linalg.inv(cam_rgb)


def assert_infos_equal(got: DngInfo, want: DngInfo, tol=1e-6):
    assert got.cfa_pattern == tuple(want.cfa_pattern)
    np.testing.assert_allclose(got.black_level, want.black_level, atol=tol)
    assert got.white_level == want.white_level
    assert got.calibration_illuminants == tuple(want.calibration_illuminants)
    for group in ("color_matrices", "camera_calibrations", "forward_matrices"):
        assert len(getattr(got, group)) == len(getattr(want, group)), group
        for a, b in zip(getattr(got, group), getattr(want, group)):
            np.testing.assert_allclose(a, b, atol=tol, err_msg=group)
    for field in ("analog_balance", "as_shot_neutral", "noise_profile"):
        np.testing.assert_allclose(getattr(got, field), getattr(want, field), rtol=tol, atol=tol * 1e-3,
                                   err_msg=field)
    assert abs(got.baseline_exposure - want.baseline_exposure) < tol
    assert got.iso == want.iso
    assert abs(got.exposure_time - want.exposure_time) < tol
    assert got.opcode_lists == want.opcode_lists
    assert (got.make, got.model, got.unique_camera_model) == (want.make, want.model, want.unique_camera_model)


# ----------------------------------------------------------------------------- round trips

@pytest.mark.parametrize("name", list(PATTERNS))
def test_round_trip_tags_and_libraw(tmp_path, name):
    pattern = PATTERNS[name]
    info = make_info(pattern)
    mosaic = random_mosaic()
    out = tmp_path / f"{name}.dng"
    write_dng(out, mosaic, info)

    got = read_dng_info(out)
    assert got.is_cfa and got.photometric == 32803 and got.cfa_string() == name
    assert (got.width, got.height) == (48, 32) and got.bits_per_sample == 16
    assert got.dng_version == (1, 4, 0, 0) and got.warnings == [] and got.pixel_data_problem is None
    assert_infos_equal(got, info)
    np.testing.assert_array_equal(read_dng_pixels(out, got), mosaic)

    with rawpy.imread(str(out)) as raw:
        desc = raw.color_desc.decode()
        assert desc == "RGBG"
        to_rgb = {"R": 0, "G": 1, "B": 2}
        libraw_pattern = tuple(to_rgb[desc[c]] for c in raw.raw_pattern.ravel())
        assert libraw_pattern == pattern
        # black_level_per_channel is indexed by LibRaw colour (R, G, B, G2), not tile position
        for pos, colour in enumerate(raw.raw_pattern.ravel()):
            assert raw.black_level_per_channel[colour] == info.black_level[pos]
        assert raw.white_level == 1023
        # camera_whitebalance = 1 / AsShotNeutral, not renormalised; 4th entry 0 = "as G"
        np.testing.assert_allclose(raw.camera_whitebalance[:3], 1 / info.as_shot_neutral, rtol=1e-6)
        np.testing.assert_array_equal(raw.raw_image, mosaic)
        # LibRaw turns the D65 ColorMatrix into its camera->sRGB matrix (float32 precision)
        np.testing.assert_allclose(raw.color_matrix[:, :3], libraw_rgb_cam(CM_D65), atol=2e-4)
        # rgb_xyz_matrix comes from LibRaw's built-in camera table, zero for cameras it does not know
        xyz = raw.rgb_xyz_matrix[:3]
        assert np.all(xyz == 0) or np.allclose(xyz, CM_D65, atol=1e-4)


@pytest.mark.parametrize("illuminants, used", [((17, 21), 1), ((21, 17), 0), ((3, 23), 1)])
def test_libraw_uses_daylight_matrix(tmp_path, illuminants, used):
    out = tmp_path / "m.dng"
    write_dng(out, random_mosaic(), make_info(calibration_illuminants=illuminants))
    with rawpy.imread(str(out)) as raw:
        np.testing.assert_allclose(raw.color_matrix[:, :3], libraw_rgb_cam((CM_A, CM_D65)[used]), atol=2e-4)


def test_tag_types(tmp_path):
    out = tmp_path / "types.dng"
    write_dng(out, random_mosaic(), make_info())
    with tifffile.TiffFile(out) as tif:
        assert len(tif.pages) == 1
        tags = {t.code: t for t in tif.pages.first.tags.values()}
        opcodes2 = tags[51009].value
    want = {
        254: (4, (0,)), 258: (3, (16,)), 259: (3, (1,)), 262: (3, (32803,)), 277: (3, (1,)),
        33421: (3, (2, 2)), 33422: (1, None), 50706: (1, None), 50707: (1, None), 50708: (2, None),
        50710: (1, None), 50711: (3, (1,)), 50717: (4, (1023,)), 50721: (10, None), 50722: (10, None),
        50723: (10, None), 50724: (10, None), 50964: (10, None), 50965: (10, None), 50727: (5, None),
        50728: (5, None), 50730: (10, None), 50778: (3, (17,)), 50779: (3, (21,)), 51041: (12, None),
        51009: (7, None), 51022: (7, None), 271: (2, None), 272: (2, None), 34855: (3, (400,)),
    }
    for code, (dtype, value) in want.items():
        assert code in tags, code
        assert int(tags[code].dtype) == dtype, (code, int(tags[code].dtype))
        if value is not None:
            assert tuple(np.atleast_1d(np.asarray(tags[code].value, dtype=np.int64))) == value, code
    assert bytes(tags[50706].value) == b"\x01\x04\x00\x00"
    assert bytes(tags[50707].value) == b"\x01\x03\x00\x00"          # opcode lists need 1.3
    assert bytes(tags[50710].value) == b"\x00\x01\x02"
    assert int(tags[50714].dtype) in (3, 4, 5)
    assert tuple(tags[50713].value) == (2, 2)
    assert 306 not in tags and 305 not in tags and 270 not in tags  # no DateTime/Software/description
    assert opcodes2 == bytes(range(40))


def test_deterministic_and_atomic(tmp_path, monkeypatch):
    mosaic, info = random_mosaic(), make_info()
    a, b = tmp_path / "a.dng", tmp_path / "b.dng"
    write_dng(a, mosaic, info)
    write_dng(b, mosaic, info)
    assert a.read_bytes() == b.read_bytes() == write_dng_bytes(mosaic, info)
    # overwrite in place; only the target is left
    write_dng(a, random_mosaic(seed=1), info)
    assert a.read_bytes() != b.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.dng", "b.dng"]
    # a failure while replacing leaves the old file and no temporary file
    before = sha(a)

    def boom(src, dst):
        assert Path(src).name.startswith(".") and Path(src).name.endswith(".tmp")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(DngError, match="a.dng"):
        write_dng(a, mosaic, info)
    monkeypatch.undo()
    assert sha(a) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.dng", "b.dng"]


def test_rationals_precision():
    rng = np.random.default_rng(3)
    values = np.concatenate([rng.normal(0, 2, 200), [0.0, 1.0, -1.0, 0.522449, 1 / 3, 1e-7, 1234.5678]])
    flat = np.array(to_rationals(values, signed=True), dtype=np.float64)
    assert np.all(np.abs(flat[0::2]) < 2**31) and np.all((flat[1::2] > 0) & (flat[1::2] < 2**31))
    np.testing.assert_allclose(flat[0::2] / flat[1::2], values, rtol=1e-9, atol=1e-9)
    assert to_rationals([0.522449], signed=False) == (522449, 1000000)
    with pytest.raises(ValueError):
        to_rationals([-0.5], signed=False)
    with pytest.raises(ValueError):
        to_rationals([np.nan], signed=True)


def test_fractional_black_three_matrices_and_single_noise(tmp_path):
    info = make_info(black_level=np.array([64.25, 64.5, 64.75, 65.125]),
                     calibration_illuminants=(17, 21, 12), color_matrices=(CM_A, CM_D65, 0.5 * (CM_A + CM_D65)),
                     camera_calibrations=(), forward_matrices=(), noise_profile=np.array([[2e-4, 3e-8]]),
                     opcode_lists={})
    out = tmp_path / "f.dng"
    write_dng(out, random_mosaic(), info)
    got = read_dng_info(out)
    assert got.dng_version == (1, 6, 0, 0)
    assert_infos_equal(got, info)
    with tifffile.TiffFile(out) as tif:
        tags = tif.pages.first.tags
        assert int(tags[50714].dtype) == 5 and int(tags[52531].dtype) == 10 and int(tags[52529].dtype) == 3
        assert bytes(tags[50707].value) == b"\x01\x01\x00\x00"
    with rawpy.imread(str(out)) as raw:
        np.testing.assert_allclose(raw.color_matrix[:, :3], libraw_rgb_cam(CM_D65), atol=2e-4)


def test_as_shot_white_xy(tmp_path):
    out = tmp_path / "xy.dng"
    write_dng(out, random_mosaic(), make_info(as_shot_neutral=None, as_shot_white_xy=np.array([0.3457, 0.3585])))
    got = read_dng_info(out)
    assert got.as_shot_neutral is None
    np.testing.assert_allclose(got.as_shot_white_xy, [0.3457, 0.3585], atol=1e-12)


@pytest.mark.parametrize("area", [(2, 2, 30, 46), (1, 1, 31, 47), (1, 0, 31, 48)])
def test_active_area_and_crop(tmp_path, area):
    mosaic = random_mosaic()
    info = make_info((1, 2, 0, 1), active_area=area, default_crop_origin=(2.0, 2.0),
                     default_crop_size=(40.0, 24.0))
    out = tmp_path / "area.dng"
    write_dng(out, mosaic, info)
    got = read_dng_info(out)
    assert got.active_area == area
    assert got.default_crop_origin == (2.0, 2.0) and got.default_crop_size == (40.0, 24.0)
    # the CFA pattern is anchored at the ActiveArea origin; LibRaw agrees (checked inside)
    top, left, bottom, right = area
    np.testing.assert_array_equal(read_dng_pixels(out), mosaic[top:bottom, left:right])


def test_geometry_that_does_not_fit_is_refused(tmp_path):
    with pytest.raises(DngError, match="active_area"):
        write_dng(tmp_path / "x.dng", random_mosaic(), make_info(active_area=(0, 0, 64, 64), width=100, height=100))
    with pytest.raises(DngError, match="crop"):
        write_dng(tmp_path / "x.dng", random_mosaic(), make_info(default_crop_size=(100.0, 10.0)))
    assert not list(tmp_path.iterdir())
    # whole-frame geometry of another camera is simply not written
    write_dng(tmp_path / "ok.dng", random_mosaic(), make_info(
        width=4000, height=3000, active_area=(0, 0, 3000, 4000),
        default_crop_origin=(0.0, 0.0), default_crop_size=(4000.0, 3000.0)))
    got = read_dng_info(tmp_path / "ok.dng")
    assert got.active_area is None and got.default_crop_size is None


# ----------------------------------------------------------------------------- bad inputs

def test_bad_files(tmp_path):
    text = tmp_path / "notes.dng"
    text.write_text("this is not a raw file\n" * 10)
    with pytest.raises(DngError, match="notes.dng: not a TIFF"):
        read_dng_info(text)
    with pytest.raises(DngError, match="file not found"):
        read_dng_info(tmp_path / "missing.dng")
    with pytest.raises(DngError, match="too short"):
        (tmp_path / "empty.dng").write_bytes(b"")
        read_dng_info(tmp_path / "empty.dng")
    plain = tmp_path / "plain.dng"
    tifffile.imwrite(plain, random_mosaic(), photometric="minisblack")
    with pytest.raises(DngError, match="DNGVersion"):
        read_dng_info(plain)
    for bad in (text, plain):
        with pytest.raises(DngError, match=bad.name):
            read_dng_pixels(bad)


def test_truncated_copies(tmp_path):
    source = tmp_path / "full.dng"
    write_dng(source, random_mosaic(), make_info())
    before = sha(source)
    data = source.read_bytes()
    # cut inside the pixel data: tags still readable, pixels refused (LibRaw alone would not say)
    cut = tmp_path / "cut.dng"
    cut.write_bytes(data[:-1000])
    info = read_dng_info(cut)
    assert info.pixel_data_problem and "truncated" in info.pixel_data_problem
    assert info.warnings == [info.pixel_data_problem]
    with pytest.raises(DngError, match="cut.dng: .*truncated"):
        read_dng_pixels(cut)
    # cut inside the header: nothing readable
    head = tmp_path / "head.dng"
    head.write_bytes(data[:100])
    with pytest.raises(DngError, match="head.dng: .*(damaged|truncated)"):
        read_dng_info(head)
    assert sha(source) == before


def test_validators():
    info = make_info(color_matrices=(), calibration_illuminants=())
    with pytest.raises(DngError, match="no ColorMatrix"):
        require_colour_tags(info)
    with pytest.raises(DngError, match="CalibrationIlluminant"):
        require_colour_tags(make_info(calibration_illuminants=(0, 21)))
    with pytest.raises(DngError, match="invertible"):
        require_colour_tags(make_info(color_matrices=(CM_A, np.zeros((3, 3)))))
    assert require_colour_tags(make_info()) is not None
    with pytest.raises(DngError, match="LinearRaw"):
        require_bayer_cfa(make_info(is_cfa=False, photometric=34892, cfa_pattern=()))
    with pytest.raises(DngError, match="Bayer"):
        require_bayer_cfa(make_info((0, 1, 2, 2)))
    with pytest.raises(DngError, match="Bayer"):
        require_bayer_cfa(make_info(cfa_repeat_dim=(6, 6)))
    assert require_bayer_cfa(make_info()) is not None


def test_write_refuses_bad_inputs(tmp_path):
    out = tmp_path / "x.dng"
    with pytest.raises(DngError, match="no ColorMatrix"):
        write_dng(out, random_mosaic(), make_info(color_matrices=(), calibration_illuminants=(),
                                                  camera_calibrations=(), forward_matrices=()))
    with pytest.raises(DngError, match="uint16"):
        write_dng(out, random_mosaic().astype(np.float32), make_info())
    with pytest.raises(DngError, match="2-D"):
        write_dng(out, np.zeros((4, 4, 3), np.uint16), make_info())
    with pytest.raises(DngError, match="Bayer"):
        write_dng(out, random_mosaic(), make_info((0, 0, 0, 0)))
    with pytest.raises(DngError, match="as_shot_neutral"):
        write_dng(out, random_mosaic(), make_info(as_shot_neutral=np.array([0.5, 0.0, 1.0])))
    assert not list(tmp_path.iterdir())


def test_missing_colour_tags_read_but_refused(tmp_path):
    """A DNG without ColorMatrix tags (hand-made with tifffile) reads, then fails the validator."""
    out = tmp_path / "nocolour.dng"
    tifffile.imwrite(out, random_mosaic(), photometric=32803, software=False, metadata=None, extratags=[
        (33421, 3, 2, (2, 2), True), (33422, 1, 4, bytes((0, 1, 1, 2)), True),
        (50706, 1, 4, bytes((1, 4, 0, 0)), True), (50717, 4, 1, (1023,), True)])
    info = read_dng_info(out)
    assert info.color_matrices == () and info.white_level == 1023 and info.cfa_string() == "RGGB"
    with pytest.raises(DngError, match="nocolour.dng: no ColorMatrix"):
        require_colour_tags(info)


# ----------------------------------------------------------------------------- real files

@pytest.mark.data
@needs_data
def test_gopro_tags_and_pixels(tmp_path):
    path = DNG_DIR / "gopro_hero6_GOPR0024.dng"
    before = sha(path)
    info = require_bayer_cfa(require_colour_tags(read_dng_info(path)))
    assert info.calibration_illuminants == (3, 23)
    assert info.cfa_string() == "RGGB" and info.white_level == 16383
    np.testing.assert_allclose(info.black_level, 0)
    np.testing.assert_allclose(info.as_shot_neutral, [0.522449, 1.0, 0.571429], atol=1e-9)
    np.testing.assert_allclose(info.noise_profile, [[1.562010002e-4, 4.880019944e-8]], rtol=1e-6)
    np.testing.assert_allclose(info.color_matrices[0][0], [1.8331, -0.8166, -0.2478], atol=1e-9)
    assert info.forward_matrices == () and info.iso == 100
    assert (info.width, info.height) == (4000, 3000) and "OpcodeList2" in info.opcode_lists
    pixels = read_dng_pixels(path, info)
    assert pixels.shape == (3000, 4000) and pixels.dtype == np.uint16 and pixels.max() <= 16383
    # the camera's tags survive our writer on a small mosaic
    out = tmp_path / "gopro_like.dng"
    write_dng(out, random_mosaic((64, 96), high=16384), info)
    again = read_dng_info(out)
    assert_infos_equal(again, info)
    with rawpy.imread(str(out)) as raw:
        np.testing.assert_allclose(raw.camera_whitebalance[:3], 1 / info.as_shot_neutral, rtol=1e-6)
    assert sha(path) == before


@pytest.mark.data
@needs_data
def test_canon_6d_linear_raw():
    path = DNG_DIR / "canon_eos_6d_linear_raw.dng"
    before = sha(path)
    info = read_dng_info(path)
    assert not info.is_cfa and info.photometric == 34892
    assert info.calibration_illuminants == (17, 21) and len(info.forward_matrices) == 2
    np.testing.assert_allclose(info.analog_balance, [2.158672, 1.0, 1.414752])
    assert info.noise_profile.shape == (3, 2)
    require_colour_tags(info)
    with pytest.raises(DngError, match="LinearRaw"):
        require_bayer_cfa(info)
    with pytest.raises(DngError, match="canon_eos_6d_linear_raw.dng: .*LinearRaw"):
        read_dng_pixels(path)
    assert sha(path) == before


@pytest.mark.data
@needs_data
def test_canon_350d_tags_without_pixels():
    path = DNG_DIR / "canon_350d_header_only.dng"
    before = sha(path)
    info = require_bayer_cfa(require_colour_tags(read_dng_info(path)))
    assert info.calibration_illuminants == (17, 21) and info.cfa_string() == "RGGB"
    assert info.white_level == 4095 and info.active_area == (14, 42, 2328, 3516)
    np.testing.assert_allclose(info.as_shot_neutral, [0.592408, 1.0, 0.501692])
    assert info.pixel_data_problem and info.warnings
    with pytest.raises(DngError, match="canon_350d_header_only.dng"):
        read_dng_pixels(path)
    assert sha(path) == before


def test_tifffile_log_records_stay_ours_when_threads_read_at_once(tmp_path, capfd):
    """DNGs read on several threads at once (as g2r-diagnose does): each reader installed and
    removed its own collector of tifffile's log records and saved and restored the logger's
    propagation, so interleaved readers left the 'tifffile' logger without propagation and without
    handler: its records ('<TiffTag.fromfile> raised TiffFileError(...)') went raw to stderr
    (diagnose campaign, seed 1: 29 of 214 cases). Now no record reaches stderr and the logger's
    state is restored."""
    import logging
    import struct
    import threading
    import warnings

    data = bytearray(write_dng_bytes(random_mosaic(), make_info()))
    assert data[:2] == b"II"
    ifd = struct.unpack_from("<I", data, 4)[0]
    struct.pack_into("<H", data, ifd + 2 + 12 + 2, 32767)   # second entry: an invalid data type
    path = tmp_path / "damaged.dng"
    path.write_bytes(bytes(data))
    logger = logging.getLogger("tifffile")
    before = (logger.propagate, list(logger.handlers))
    barrier = threading.Barrier(6)

    def read_many():
        barrier.wait()
        for _ in range(30):
            try:
                read_dng_info(path)
            except DngError:
                pass

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # our own one-line warning naming the file
        threads = [threading.Thread(target=read_many) for _ in range(6)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert (logger.propagate, list(logger.handlers)) == before
    logger.error("a record after the readers: handled as before")   # no handler, propagation on
    assert "TiffTag" not in capfd.readouterr().err
