"""The reader's green-phase check never refuses a sound file on a guess (issue 44).

Before issue 44 the check refused a raster when its tagged green sites differed more than twice as
much as red against blue, which assumes content that is smooth at the pixel scale: `g2r-convert`'s
own conversions of white noise and of 1-px line patterns under a non-neutral light were refused.
Here: such conversions (two profiles, every CFA phase) are read; a raster shifted by one column or
one row of a smooth scene (and of the real GoPro frame) is still refused; a shifted raster the
check cannot be sure of (white noise, a flat field) is read with a warning in `info.warnings`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from g2r_jax.io.dng_info import DngError
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
from g2r_jax.io.dng_write import write_dng
from g2r_jax.io.pixel_layout import decoded_finding, decoded_problem
from test_io_dng import make_info
from test_io_pixel_layout import GOPRO, RGGB, needs_gopro, scene_mosaic

# camera neutrals (raw response to white, G = 1): red and blue far below green, as under a light
# the camera is not balanced for; the second also makes red and blue differ from each other
LIGHTS = {"cast": (0.3, 1.0, 0.3), "cyan": (0.3, 1.0, 0.6)}
CONTENT = ("noise", "grey_noise", "columns", "rows", "checker")
MAY_BE_SHIFTED = "may be shifted against its CFAPattern"


def content_image(kind: str, rng, shape=(64, 96)) -> np.ndarray:
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]]
    if kind == "noise":
        return rng.integers(0, 256, shape + (3,)).astype(np.uint8)
    if kind == "grey_noise":
        return np.repeat(rng.integers(0, 256, shape + (1,)), 3, axis=2).astype(np.uint8)
    on = {"columns": columns % 2 == 0, "rows": rows % 2 == 0, "checker": (rows + columns) % 2 == 0}[kind]
    return np.where(on[..., None], 255, 0).astype(np.uint8) * np.ones(3, np.uint8)


def rephased(mosaic: np.ndarray, info, rows: int, columns: int):
    """The same scene cropped by `rows`/`columns` at the top left: a sound file of another phase."""
    height, width = mosaic.shape
    order = [2 * ((i + rows) % 2) + (j + columns) % 2 for i in (0, 1) for j in (0, 1)]
    return (np.ascontiguousarray(mosaic[rows:height - 2 + rows, columns:width - 2 + columns]),
            dataclasses.replace(info, cfa_pattern=tuple(info.cfa_pattern[k] for k in order),
                                black_level=np.asarray(info.black_level)[order], warnings=[], path=""))


@pytest.fixture(scope="module")
def conversions(tmp_path_factory):
    """{(profile, light, content): DNG path}: g2r-convert's conversions (the library call it runs)."""
    import g2r_jax
    from g2r_jax.batch.conversion import ConvertOptions, convert_files

    folder = tmp_path_factory.mktemp("valid_content")
    rng = np.random.default_rng(44)
    inputs, neutrals = [], []
    for light, neutral in LIGHTS.items():
        for kind in CONTENT:
            inputs.append(folder / f"{kind}_{light}.png")
            Image.fromarray(content_image(kind, rng)).save(inputs[-1])
            neutrals.append(neutral)
    made = {}
    for profile in ("NikonD40", "gopro_hero6"):   # BGGR and RGGB
        out = folder / profile
        result = convert_files(inputs, g2r_jax.load_profile(profile), out, neutrals=np.array(neutrals),
                               options=ConvertOptions(seed=1, progress=False))
        assert result.ok, result.errors
        for record in result.records:
            kind, light = Path(record["output"]).stem.rsplit("_", 1)
            made[(profile, light, kind)] = out / record["output"]
    return made


def test_conversions_of_noise_and_lines_are_read_in_every_phase(conversions, tmp_path):
    """White noise and 1-px lines under non-neutral lights: never refused (before issue 44 the
    NikonD40's noise and lines under 'cast' were), white noise not even warned about."""
    phases = set()
    for (profile, light, kind), path in conversions.items():
        info = read_dng_info(path)
        mosaic = read_dng_pixels(path, info)
        for rows, columns in ((0, 0), (0, 1), (1, 0), (1, 1)):
            variant, variant_info = rephased(mosaic, info, rows, columns)
            target = tmp_path / f"{profile}_{light}_{kind}_{rows}{columns}.dng"
            write_dng(target, variant, variant_info)
            read_info = read_dng_info(target)
            np.testing.assert_array_equal(read_dng_pixels(target, read_info), variant)   # no DngError
            phases.add(read_info.cfa_pattern)
            if kind.endswith("noise"):
                assert read_info.warnings == [], (target.name, read_info.warnings)
    assert len(phases) == 4


def test_a_shifted_smooth_scene_is_still_refused_by_name(tmp_path):
    mosaic = scene_mosaic()
    for axis in (1, 0):
        for step in (1, -1):
            path = tmp_path / f"shifted_{axis}_{step}.dng"
            write_dng(path, np.roll(mosaic, step, axis=axis), make_info(RGGB))
            with pytest.raises(DngError, match=f"{path.name}: the pixel data is shifted against its CFAPattern"):
                read_dng_pixels(path)


def test_a_shifted_noise_conversion_is_read_with_a_warning(conversions, tmp_path):
    """Shifted white noise: red and blue (now on the tagged diagonal) are distributed apart under
    'cyan', the greens alike, but pixel to pixel no pair is closer than another: the distributions
    alone point to the shift, so the file is read, with a warning (before: read without a word)."""
    for profile in ("NikonD40", "gopro_hero6"):
        path = conversions[(profile, "cyan", "noise")]
        info = read_dng_info(path)
        mosaic = read_dng_pixels(path, info)
        for axis in (1, 0):
            target = tmp_path / f"{profile}_noise_shifted_{axis}.dng"
            write_dng(target, np.roll(mosaic, -1, axis=axis), info)
            read_info = read_dng_info(target)
            with pytest.warns(UserWarning, match=f"{target.name}: the pixel data {MAY_BE_SHIFTED}"):
                read_dng_pixels(target, read_info)
            assert any(MAY_BE_SHIFTED in line for line in read_info.warnings), (target.name, read_info.warnings)


def test_lines_that_match_a_shifted_flat_field_are_warned_about_not_refused():
    """Columns 1 px wide whose red sites read as the blue ones (R x bright = B x dark = 400) are,
    in the raster, exactly a flat field (R 200, G 400, B 800) shifted by one column: neither
    reading can be ruled out, so the file is read with a warning (before issue 44: refused)."""
    rng = np.random.default_rng(3)
    tile = np.array([[400.0, 200.0], [800.0, 400.0]])   # R bright, G dark | G bright, B dark
    lines = np.round(64 + np.tile(tile, (48, 64)) + rng.normal(0, 4, (96, 128))).astype(np.uint16)
    found = decoded_finding(lines, [64] * 4, 1023, RGGB)
    assert found.refusal is None and MAY_BE_SHIFTED in found.warning
    assert decoded_problem(lines, [64] * 4, 1023, RGGB) is None
    flat = np.roll(lines, 1, axis=1)   # the flat field itself, in phase: nothing to say
    assert decoded_finding(flat, [64] * 4, 1023, RGGB) == type(found)()


def test_what_carries_no_evidence_passes_silently():
    rng = np.random.default_rng(5)
    shape = (96, 128)
    for raster in (rng.normal(64, 2, shape), np.full(shape, 1023), np.full(shape, 64),   # dark, saturated, black
                   64 + rng.integers(0, 900, shape),                                      # white noise, one gain
                   np.roll(64 + rng.integers(0, 900, shape), 1, axis=1)):
        found = decoded_finding(np.round(raster).astype(np.uint16), [64] * 4, 1023, RGGB)
        assert found == type(found)(), found


@pytest.mark.data
@needs_gopro
def test_the_real_gopro_frame_shifted_is_refused():
    info = read_dng_info(GOPRO)
    mosaic = read_dng_pixels(GOPRO, info)
    assert info.warnings == []
    pixel_back = np.roll(mosaic.ravel(), 1).reshape(mosaic.shape)   # StripOffsets 2 bytes early
    for raster in (pixel_back, np.roll(mosaic, -1, axis=0), np.roll(mosaic, -1, axis=1)):
        found = decoded_finding(raster, info.black_level, info.white_level, info.cfa_pattern)
        assert found.refusal and "shifted against its CFAPattern" in found.refusal
