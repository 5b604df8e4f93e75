"""DNG opcode lists (g2r_jax.io.opcodes) and lens-shading gains (g2r_jax.sensor.shading).

Gains are checked against closed forms: bilinear interpolation reproduces a + b v + c h + d v h
exactly inside the map (DNG spec 1.6 ch. 7 'GainMap'), FixVignetteRadial is 1 + k0 r^2 + ...
"""

from __future__ import annotations

import dataclasses
import struct
from pathlib import Path

import numpy as np
import pytest

from g2r_jax.io.dng_info import DngError, DngInfo
from g2r_jax.io.dng_read import read_dng_info
from g2r_jax.io.dng_write import write_dng
from g2r_jax.io.opcodes import FixVignetteRadial, GainMap, Opcode, encode_opcode_list, parse_opcode_list
from g2r_jax.sensor.shading import opcode_list_image_size, rescale_opcode_list, shading_gain_planes
from g2r_jax.sensor import from_planes

DNG_DIR = Path(__file__).parents[1] / ".." / "shared" / "data" / "dng"
GOPRO = DNG_DIR / "gopro_hero6_GOPR0024.dng"
CANON = DNG_DIR / "canon_eos_6d_linear_raw.dng"
needs_data = pytest.mark.skipif(not GOPRO.is_file() or not CANON.is_file(), reason="../shared/data absent")


def gains_mosaic(ops, height, width) -> np.ndarray:
    """(H, W) gain of an opcode list, through the public planar API."""
    return np.asarray(from_planes(shading_gain_planes({"OpcodeList2": encode_opcode_list(ops)}, height, width)))


def constant_map(value, **area) -> GainMap:
    return GainMap(gains=np.full((2, 2, 1), value, np.float32), **area)


def bilinear(v, h):
    return 1.0 + 0.5 * v + 0.25 * h + 0.3 * v * h


def analytic_map(**area) -> GainMap:
    """A 5x7 map over v in [0.1, 0.9], h in [0.2, 0.8] holding `bilinear` at its points."""
    v = 0.1 + 0.2 * np.arange(5)
    h = 0.2 + 0.1 * np.arange(7)
    grid = bilinear(v[:, None], h[None, :]).astype(np.float32)[:, :, None]
    return GainMap(gains=grid, spacing=(0.2, 0.1), origin=(0.1, 0.2), **area)


def expected_analytic(height, width):
    v = np.clip((np.arange(height) + 0.5) / height, 0.1, 0.9)[:, None]
    h = np.clip((np.arange(width) + 0.5) / width, 0.2, 0.8)[None, :]
    return bilinear(v, h)


# ----------------------------------------------------------------------------- encoding

def test_encode_parse_round_trip_synthetic():
    ops = [analytic_map(top=0, left=1, bottom=40, right=60, row_pitch=2, col_pitch=2, flags=3,
                        version=(1, 4, 0, 0)),
           FixVignetteRadial((0.3, -0.1, 0.02, 0.0, 1e-3), cx=0.45, cy=0.55),
           Opcode(4, (1, 3, 0, 0), 1, struct.pack(">II", 0, 1))]       # FixBadPixelsConstant, opaque
    data = encode_opcode_list(ops)
    back = parse_opcode_list(data)
    assert encode_opcode_list(back) == data
    assert [op.name for op in back] == ["GainMap", "FixVignetteRadial", "FixBadPixelsConstant"]
    gm = back[0]
    assert (gm.top, gm.left, gm.bottom, gm.right, gm.row_pitch, gm.flags, gm.version) == (0, 1, 40, 60, 2, 3, (1, 4, 0, 0))
    np.testing.assert_array_equal(gm.gains, ops[0].gains)
    assert back[1] == ops[1] and back[2] == ops[2]
    assert parse_opcode_list(data.hex()) and encode_opcode_list([]) == b"\x00\x00\x00\x00"


@pytest.mark.data
@needs_data
@pytest.mark.parametrize("path", [GOPRO, CANON], ids=["gopro", "canon"])
def test_real_lists_round_trip_byte_identical(path):
    data = read_dng_info(path).opcode_lists["OpcodeList2"]
    ops = parse_opcode_list(data, path)
    assert encode_opcode_list(ops) == data
    if path == GOPRO:   # 4 GainMaps, one per Bayer position (Top/Left phase, pitch 2), 23x23 maps
        assert len(data) == 8836 and [op.name for op in ops] == ["GainMap"] * 4
        assert {(op.top, op.left) for op in ops} == {(0, 0), (0, 1), (1, 0), (1, 1)}
        assert all((op.bottom, op.right, op.row_pitch, op.col_pitch, op.gains.shape)
                   == (3000, 4000, 2, 2, (23, 23, 1)) for op in ops)
    else:               # LinearRaw: one MapPolynomial per colour plane, kept opaque
        assert len(data) == 256 and [op.name for op in ops] == ["MapPolynomial"] * 3


# ----------------------------------------------------------------------------- gains

def test_gain_map_bilinear_and_clamped_edges():
    got = gains_mosaic([analytic_map(top=0, left=0, bottom=40, right=60)], 40, 60)
    np.testing.assert_allclose(got, expected_analytic(40, 60), rtol=2e-6)


def test_gain_map_pitch_and_plane_selection():
    per_position = [constant_map(2.0 + k, top=dy, left=dx, bottom=20, right=30, row_pitch=2, col_pitch=2)
                    for k, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1)))]
    planes = shading_gain_planes({"OpcodeList2": encode_opcode_list(per_position)}, 20, 30, (0, 1, 1, 2))
    assert planes.shape == (4, 10, 15) and planes.dtype == np.float32
    np.testing.assert_array_equal(planes, np.array([2, 3, 4, 5], np.float32)[:, None, None] * np.ones((4, 10, 15)))

    got = gains_mosaic([constant_map(1.5, top=4, left=6, bottom=10, right=20)], 20, 30)
    want = np.ones((20, 30))
    want[4:10, 6:20] = 1.5
    np.testing.assert_array_equal(got, want)

    got = gains_mosaic([constant_map(1.5, top=3, left=0, bottom=11, right=30, row_pitch=4, col_pitch=3)], 20, 30)
    want = np.ones((20, 30))
    want[3:11:4, 0:30:3] = 1.5
    np.testing.assert_array_equal(got, want)

    # a plane the CFA image does not have: no effect; an empty area: the whole image (SDK reading)
    assert np.all(gains_mosaic([constant_map(3.0, top=0, left=0, bottom=20, right=30, plane=1)], 20, 30) == 1)
    assert np.all(gains_mosaic([constant_map(3.0, top=0, left=0, bottom=0, right=0)], 20, 30) == 3)
    assert np.all(shading_gain_planes({}, 20, 30) == 1)
    assert np.all(shading_gain_planes({"OpcodeList3": encode_opcode_list(per_position)}, 20, 30) == 1)


def test_fix_vignette_radial_and_composition():
    k = (0.4, 0.1, 0.0, 0.0, -0.05)
    height, width, cx, cy = 20, 30, 0.25, 0.75
    dy = np.arange(height)[:, None] + 0.5 - cy * height
    dx = np.arange(width)[None, :] + 0.5 - cx * width
    r2 = (dy**2 + dx**2) / (15.0**2 + 22.5**2)        # farthest corner: 15 rows up, 22.5 columns right
    want = 1 + 0.4 * r2 + 0.1 * r2**2 - 0.05 * r2**5
    vignette = FixVignetteRadial(k, cx=cx, cy=cy)
    np.testing.assert_allclose(gains_mosaic([vignette], height, width), want, rtol=2e-6)
    both = gains_mosaic([vignette, constant_map(2.0, top=0, left=0, bottom=20, right=30)], height, width)
    np.testing.assert_allclose(both, 2 * want, rtol=2e-6)


@pytest.mark.data
@needs_data
def test_gopro_gain_planes_plausible():
    info = read_dng_info(GOPRO)
    hex_pairs = tuple((name, data.hex()) for name, data in info.opcode_lists.items())   # as in a profile
    planes = shading_gain_planes(hex_pairs, info.height, info.width, info.cfa_pattern)
    assert planes.shape == (4, 1500, 2000) and np.all(np.isfinite(planes))
    assert np.all(np.abs(planes[:, 745:755, 995:1005] - 1) < 2e-3)                   # centre: no correction
    corners = planes[:, [0, 0, -1, -1], [0, -1, 0, -1]]
    assert np.all(corners > 1.7) and planes.max() < 2.1 and planes.min() >= 1 - 1e-6
    assert np.max(np.abs(planes / planes.mean(axis=0) - 1)) < 0.02                   # same lens, 4 positions


# ----------------------------------------------------------------------------- rescaling

def test_rescale_keeps_relative_geometry():
    ops = [analytic_map(top=dy, left=dx, bottom=400, right=600, row_pitch=2, col_pitch=2)
           for dy in (0, 1) for dx in (0, 1)]
    data = encode_opcode_list(ops)
    assert opcode_list_image_size(data) == (400, 600)
    small = rescale_opcode_list(data, None, (40, 60))
    assert [(o.top, o.left, o.bottom, o.right) for o in parse_opcode_list(small)] == [
        (0, 0, 40, 60), (0, 1, 40, 60), (1, 0, 40, 60), (1, 1, 40, 60)]
    got = np.asarray(from_planes(shading_gain_planes({"OpcodeList2": small}, 40, 60)))
    np.testing.assert_allclose(got, expected_analytic(40, 60), rtol=2e-6)
    assert rescale_opcode_list(small, (40, 60), (400, 600)) == data                  # only Top..Right changed

    sub = encode_opcode_list([constant_map(2.0, top=101, left=40, bottom=301, right=560, row_pitch=2)])
    [scaled] = parse_opcode_list(rescale_opcode_list(sub, (400, 600), (40, 60)))
    assert (scaled.top, scaled.left, scaled.bottom, scaled.right) == (11, 4, 30, 56)  # Top keeps odd phase


def test_rescale_other_opcodes():
    bad_pixels = Opcode(5, (1, 3, 0, 0), 0, struct.pack(">5I", 0, 1, 0, 10, 12))    # FixBadPixelsList
    data = encode_opcode_list([bad_pixels, FixVignetteRadial((0.2, 0, 0, 0, 0))])
    assert rescale_opcode_list(data, (40, 60), (40, 60)) == data
    with pytest.raises(DngError, match="FixBadPixelsList .* cannot be rescaled"):
        rescale_opcode_list(data, (40, 60), (20, 30))
    only = parse_opcode_list(rescale_opcode_list(data, (40, 60), (20, 30), shading_only=True))
    assert [op.name for op in only] == ["FixVignetteRadial"]
    assert rescale_opcode_list(encode_opcode_list([bad_pixels]), (40, 60), (20, 30), shading_only=True) == b""
    with pytest.raises(DngError, match="cannot tell the image size"):
        rescale_opcode_list(data, None, (20, 30))


@pytest.mark.data
@needs_data
def test_rescale_real_lists():
    gopro = read_dng_info(GOPRO).opcode_lists["OpcodeList2"]
    small = rescale_opcode_list(gopro, (3000, 4000), (300, 400))
    assert len(small) == len(gopro) and rescale_opcode_list(small, (300, 400), (3000, 4000)) == gopro
    full = shading_gain_planes({"OpcodeList2": gopro}, 3000, 4000)
    reduced = shading_gain_planes({"OpcodeList2": small}, 300, 400)
    # nearly the same relative position (within half a 10x10 block) sees nearly the same gain
    np.testing.assert_allclose(reduced, full[:, 4::10, 4::10], atol=0.02)
    canon = read_dng_info(CANON).opcode_lists["OpcodeList2"]
    polys = parse_opcode_list(rescale_opcode_list(canon, (816, 1224), (408, 612)))
    assert [struct.unpack(">4I", op.params[:16]) for op in polys] == [(0, 0, 408, 612)] * 3
    assert rescale_opcode_list(canon, None, (408, 612), shading_only=True) == b""


# ----------------------------------------------------------------------------- bad input

def test_malformed_lists_raise_clear_errors():
    good = encode_opcode_list([constant_map(2.0, top=0, left=0, bottom=8, right=8),
                               FixVignetteRadial((0.1, 0, 0, 0, 0))])
    cases = {
        b"": "too short",
        good[:3]: "too short",
        good[:10]: "truncated: .* opcode 0 header",
        good[:60]: r"truncated: opcode 0 \(GainMap\) needs 92 parameter bytes",
        good + b"\x00": "1 bytes after its 2 opcodes",
        struct.pack(">I", 3) + good[4:]: "announces 3 opcodes",
        good[:4] + good[4:16] + struct.pack(">I", 88) + good[20:108] + good[112:]: "88 parameter bytes, expected 92",
        struct.pack(">I", 1) + good[112:124] + struct.pack(">I", 48) + good[128:176]: "48 parameter bytes, expected 56",
    }
    for data, message in cases.items():
        with pytest.raises(DngError, match="OpcodeList2: .*" + message):
            parse_opcode_list(data, "OpcodeList2")
    zero_pitch = bytearray(good)
    zero_pitch[20 + 24:20 + 28] = b"\x00\x00\x00\x00"                               # RowPitch = 0
    with pytest.raises(DngError, match="zero MapPoints/MapPlanes/Planes/pitch"):
        parse_opcode_list(bytes(zero_pitch))
    with pytest.raises(DngError, match="non-positive gains"):
        shading_gain_planes({"OpcodeList2": encode_opcode_list([constant_map(0.0, top=0, left=0, bottom=8, right=8)])}, 8, 8)
    with pytest.raises(ValueError, match="even"):
        shading_gain_planes({}, 7, 8)


# ----------------------------------------------------------------------------- written DNGs

def test_written_dng_keeps_opcode_list_and_opens_in_rawpy(tmp_path):
    """Independent check: tifffile writes the tag, our reader and LibRaw (rawpy) open the file.

    LibRaw 0.22 (rawpy 0.28) ignores OpcodeList2: raw_image is the stored mosaic and a rendering
    equals the one without the list; a LibRaw that applied the gain of 2 would double it.
    """
    rawpy = pytest.importorskip("rawpy")
    matrix = np.array([[0.6018, -0.0617, -0.0965], [-0.8645, 1.5881, 0.2975], [-0.153, 0.1719, 0.7642]])
    info = DngInfo(make="G2R", model="Shading", cfa_pattern=(0, 1, 1, 2), black_level=np.zeros(4),
                   white_level=1023.0, calibration_illuminants=(21,), color_matrices=(matrix,),
                   as_shot_neutral=np.array([0.5, 1.0, 0.6]))
    mosaic = np.full((32, 48), 100, np.uint16)
    lists = encode_opcode_list([constant_map(2.0, top=0, left=0, bottom=32, right=48)])
    renders = []
    for name, opcode_lists in (("plain", {}), ("shaded", {"OpcodeList2": lists})):
        path = tmp_path / f"{name}.dng"
        write_dng(path, mosaic, dataclasses.replace(info, opcode_lists=opcode_lists))
        assert read_dng_info(path).opcode_lists == opcode_lists
        with rawpy.imread(str(path)) as raw:
            np.testing.assert_array_equal(raw.raw_image_visible, mosaic)
            renders.append(raw.postprocess(gamma=(1, 1), no_auto_bright=True, output_bps=16, user_flip=0,
                                           user_wb=[1, 1, 1, 1], output_color=rawpy.ColorSpace.raw).astype(float))
    ratio = renders[1].mean() / renders[0].mean()
    assert ratio == pytest.approx(1.0) or ratio == pytest.approx(2.0, rel=0.02)
