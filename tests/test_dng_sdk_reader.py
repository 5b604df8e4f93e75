"""Every kind of DNG g2r_jax writes, read back by Adobe's DNG SDK (1.7.1, through the `dngpy`
bindings): the same raw pixels, CFA pattern and AsShotNeutral as ours, and no warning from the
SDK's own validation (built with qDNGValidate: it prints what `dng_validate` prints while parsing)
except the four 'too little padding' lines (no pixels outside the image; see the docs page
validation/dng_conformance.md). Skipped when dngpy is not installed."""

from __future__ import annotations

import dataclasses
import os
import tempfile

import numpy as np
import pytest

dngpy = pytest.importorskip("dngpy")

from g2r_jax.io import dng_write  # noqa: E402
from g2r_jax.io.dng_info import DngInfo  # noqa: E402
from g2r_jax.io.opcodes import GainMap, encode_opcode_list  # noqa: E402

CM_A = np.array([[0.7861, -0.2131, -0.0346], [-0.3938, 1.1473, 0.2869], [-0.0377, 0.1439, 0.6588]])
CM_D65 = np.array([[0.6722, -0.0635, -0.0963], [-0.4287, 1.2460, 0.2028], [-0.0908, 0.2162, 0.5668]])
FM_A = np.array([[0.7763, 0.0065, 0.1815], [0.2844, 0.7035, 0.0121], [0.0, 0.0, 0.8249]])
FM_D65 = np.array([[0.7186, 0.1228, 0.1229], [0.2719, 0.8207, -0.0926], [0.0, -0.1124, 0.9374]])
PADDING = "Too little padding"
LENS_SHADING = encode_opcode_list([GainMap(top=0, left=0, bottom=48, right=64, plane=0, planes=1,
                                           gains=np.array([[[1.2], [1.1]], [[1.1], [1.0]]], np.float32))])


def base_info(**changes) -> DngInfo:
    info = DngInfo(make="G2R", model="SDK check", unique_camera_model="G2R SDK check", cfa_pattern=(0, 1, 1, 2),
                   black_level=np.full(4, 512.0), white_level=16383.0, calibration_illuminants=(17, 21),
                   color_matrices=(CM_A, CM_D65), as_shot_neutral=np.array([0.52, 1.0, 0.61]),
                   noise_profile=np.array([[2e-5, 1e-7]]), iso=400.0, exposure_time=1 / 60)
    return dataclasses.replace(info, **changes)


KINDS = {
    "RGGB, A and D65": base_info(),
    "BGGR": base_info(cfa_pattern=(2, 1, 1, 0)),
    "GRBG, forward matrices, calibrations, analog balance, noise per plane": base_info(
        cfa_pattern=(1, 0, 2, 1), forward_matrices=(FM_A, FM_D65),
        camera_calibrations=(np.diag([1.01, 1.0, 0.99]), np.diag([1.02, 1.0, 0.98])),
        analog_balance=np.array([1.0, 1.0, 1.0]), noise_profile=np.array([[2e-5, 1e-7], [1.5e-5, 8e-8], [2.5e-5, 1.2e-7]])),
    "GBRG, one matrix": base_info(cfa_pattern=(1, 2, 0, 1), calibration_illuminants=(21,), color_matrices=(CM_D65,)),
    "three illuminants with IlluminantData (DNG 1.6)": base_info(
        calibration_illuminants=(17, 21, 255), color_matrices=(CM_A, CM_D65, 0.5 * (CM_A + CM_D65)),
        illuminant_data=(None, None, (0.3805, 0.3768))),
    "fractional black per tile position": base_info(black_level=np.array([512.25, 512.5, 511.75, 512.0])),
    "AsShotWhiteXY instead of AsShotNeutral": base_info(as_shot_neutral=None, as_shot_white_xy=np.array([0.3457, 0.3585])),
    "ActiveArea and DefaultCrop": base_info(active_area=(2, 2, 46, 62), default_crop_origin=(2.0, 2.0),
                                            default_crop_size=(56.0, 40.0)),
    "lens-shading OpcodeList2": base_info(opcode_lists={"OpcodeList2": LENS_SHADING}),
}
COMPRESSIONS = [c for c in getattr(dng_write, "COMPRESSIONS", ("none",))]


def read_with_sdk(path):
    """(dngpy.Dng, the SDK's warning lines) for `path`; the SDK prints to file descriptor 2."""
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            dng = dngpy.Dng(str(path))
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        sink.seek(0)
        lines = [line.strip() for line in sink.read().decode("utf-8", "replace").splitlines() if line.strip()]
    return dng, lines


def write(path, mosaic, info, compression):
    if compression == "none":
        dng_write.write_dng(path, mosaic, info)
    else:
        path.write_bytes(dng_write.write_dng_bytes(mosaic, info, where=path, compression=compression))


@pytest.mark.parametrize("compression", COMPRESSIONS)
@pytest.mark.parametrize("kind", list(KINDS))
def test_sdk_reads_what_we_write(tmp_path, kind, compression):
    info = KINDS[kind]
    mosaic = np.random.default_rng(7).integers(400, 16384, (48, 64)).astype(np.uint16)
    path = tmp_path / "kind.dng"
    write(path, mosaic, info, compression)
    dng, warnings = read_with_sdk(path)
    assert [w for w in warnings if PADDING not in w] == [], warnings

    pixels = np.asarray(dng.raw_pixels)
    assert pixels.shape[-1] == 1 and pixels.dtype == np.uint16
    np.testing.assert_array_equal(pixels[..., 0], mosaic)              # stage 1: the whole frame, unchanged
    assert dng.get_bayer_pattern() == info.cfa_string()
    if info.as_shot_neutral is not None:
        np.testing.assert_allclose(dng.get_white_balance(), info.as_shot_neutral / info.as_shot_neutral[1],
                                   rtol=1e-6)
    else:   # AsShotWhiteXY: no AsShotNeutral for the SDK either (the bindings report the tag only)
        assert list(dng.get_white_balance()) == []
    meta = dng.metadata
    size = tuple(int(v) for v in info.default_crop_size) if info.default_crop_size else (64, 48)
    assert (meta.make, meta.model, meta.width, meta.height) == (info.make, info.model, *size)   # the default crop
    assert meta.iso == info.iso and meta.exposure_time == pytest.approx(info.exposure_time)


@pytest.mark.slow
def test_sdk_reads_a_converted_dng(tmp_path):
    """A DNG from `g2r-convert` (shipped profile, sampled illuminant and noise)."""
    from PIL import Image

    from g2r_jax.cli import convert
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels

    source = tmp_path / "in"
    source.mkdir()
    image = np.random.default_rng(0).integers(0, 256, (48, 64, 3)).astype(np.uint8)
    Image.fromarray(image).save(source / "chart.png")
    out = tmp_path / "out"
    assert convert.main([str(source), "-o", str(out), "--profile", "gopro_hero6"]) == 0
    path = next(out.glob("*.dng"))
    dng, warnings = read_with_sdk(path)
    assert [w for w in warnings if PADDING not in w] == [], warnings
    ours = read_dng_info(path)
    np.testing.assert_array_equal(np.asarray(dng.raw_pixels)[..., 0], read_dng_pixels(path, ours))
    assert dng.get_bayer_pattern() == ours.cfa_string()
    np.testing.assert_allclose(dng.get_white_balance(), ours.as_shot_neutral / ours.as_shot_neutral[1], rtol=1e-6)
