"""The DNG reader refuses pixel data that contradicts its tags, by name (issue 34).

Each class the fuzzer of issue 34 found (BitsPerSample 8/12/0/1 on 16-bit data, ImageWidth one
column short, StripOffsets 0) and its neighbours (byte counts, rows per strip, WhiteLevel,
Compression, lossless-JPEG tiles, data read one pixel off) on a small scene written here, on its
lossless-JPEG twin, on the output of `g2r-convert --example` and on a real GoPro DNG; and the whole
mutation table of tests/fuzz_tags.py: no mutated file is decoded into other pixels without a word.
"""

from __future__ import annotations

import collections
import hashlib
from pathlib import Path

import numpy as np
import pytest

import fuzz_tags as ft
from g2r_jax.io.dng_info import DngError
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
from g2r_jax.io.dng_write import write_dng
from g2r_jax.io.pixel_layout import decoded_problem
from test_io_dng import make_info

GOPRO = Path(__file__).parents[1] / ".." / "shared" / "data" / "dng" / "gopro_hero6_GOPR0024.dng"
needs_gopro = pytest.mark.skipif(not GOPRO.is_file(), reason="../shared/data absent")
RGGB = (0, 1, 1, 2)


def scene_mosaic(shape=(96, 128), seed=0) -> np.ndarray:
    """An RGGB mosaic of a smooth coloured scene with noise, 10-bit levels above black 64."""
    rng = np.random.default_rng(seed)
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]]
    shade = 0.5 + 0.5 * np.sin(columns / 17.0) * np.cos(rows / 23.0)
    level = np.where((rows % 2 == 0) & (columns % 2 == 0), 300.0, np.where((rows % 2 == 1) & (columns % 2 == 1),
                                                                             150.0, 600.0))
    mosaic = 64 + level * shade + rng.normal(0, 3, shape)
    return np.clip(np.round(mosaic), 0, 1023).astype(np.uint16)


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    folder = tmp_path_factory.mktemp("layout_seeds")
    mosaic = scene_mosaic()
    info = make_info(RGGB)
    plain, tiled = folder / "plain.dng", folder / "tiled.dng"
    write_dng(plain, mosaic, info)
    write_dng(tiled, mosaic, info, compression="ljpeg")
    return {"plain": plain, "tiled": tiled, "mosaic": mosaic}


def mutated(tmp_path, seed: Path, code: int, value: int, name="bad.dng") -> Path:
    data = seed.read_bytes()
    path = tmp_path / name
    path.write_bytes(ft.with_value(data, ft.raw_entries(data), code, value))
    return path


def test_clean_files_read_as_written(seeds):
    for kind in ("plain", "tiled"):
        info = read_dng_info(seeds[kind])
        assert info.pixel_data_problem is None
        np.testing.assert_array_equal(read_dng_pixels(seeds[kind], info), seeds["mosaic"])


@pytest.mark.parametrize("bits", [8, 12, 0, 1, 10, 14, 32, 33])
def test_bits_per_sample_that_lies_is_refused_by_name(seeds, tmp_path, bits):
    for kind in ("plain", "tiled"):
        path = mutated(tmp_path, seeds[kind], 258, bits, f"{kind}_bits{bits}.dng")
        if kind == "tiled" and 10 <= bits <= 16:   # lossless JPEG of 10 bits: tags consistent, pixels the same
            np.testing.assert_array_equal(read_dng_pixels(path), seeds["mosaic"])
        elif kind == "tiled":
            with pytest.raises(DngError, match=f"{path.name}: "):
                read_dng_pixels(path)
        else:
            with pytest.raises(DngError, match=f"{path.name}: .*(BitsPerSample|bits)"):
                read_dng_info(path)


@pytest.mark.parametrize("code, delta", [(256, -1), (256, 1), (257, -1), (257, 1), (256, -2), (278, -1)])
def test_uncompressed_size_that_lies_is_refused(seeds, tmp_path, code, delta):
    data = seeds["plain"].read_bytes()
    entries = ft.raw_entries(data)
    path = mutated(tmp_path, seeds["plain"], code, ft.current(data, entries, code) + delta)
    with pytest.raises(DngError, match=r"bad.dng: .*size tags disagree with the data"):
        read_dng_pixels(path)


@pytest.mark.parametrize("offset", [0, 1, 8, 16])
def test_strip_offsets_on_the_header_are_refused(seeds, tmp_path, offset):
    path = mutated(tmp_path, seeds["plain"], 273, offset)
    with pytest.raises(DngError, match=r"bad.dng: pixel data at bytes .* lies on the (TIFF header|IFD)"):
        read_dng_info(path)


@pytest.mark.parametrize("change", [-2, 2, 1])
def test_byte_counts_that_lie_are_refused(seeds, tmp_path, change):
    data = seeds["plain"].read_bytes()
    count = ft.current(data, ft.raw_entries(data), 279)
    with pytest.raises(DngError, match=r"bad.dng: (uncompressed strip 0 has|raw image data runs to byte)"):
        read_dng_pixels(mutated(tmp_path, seeds["plain"], 279, count + change))


def test_white_level_below_the_data_is_refused(seeds, tmp_path):
    # uncompressed: the stored values are sampled when the tags are read (profile fitting reads tags only)
    with pytest.raises(DngError, match=r"bad.dng: .* of the stored values .* exceed WhiteLevel 255"):
        read_dng_info(mutated(tmp_path, seeds["plain"], 50717, 255))
    # lossless JPEG: found when the pixels are decoded
    path = mutated(tmp_path, seeds["tiled"], 50717, 255)
    assert read_dng_info(path).white_level == 255
    with pytest.raises(DngError, match=r"bad.dng: .* of the decoded pixels exceed WhiteLevel 255"):
        read_dng_pixels(path)


def test_compression_that_lies_is_refused(seeds, tmp_path):
    with pytest.raises(DngError, match=r"bad.dng: strip 0 .* \(no SOI marker\)"):
        read_dng_info(mutated(tmp_path, seeds["plain"], 259, 7))
    data = seeds["tiled"].read_bytes()
    offset = ft.current(data, ft.raw_entries(data), 324)
    for shift in (-1, -2):
        with pytest.raises(DngError, match=r"bad.dng: tile 0 .* \(no SOI marker\)"):
            read_dng_info(mutated(tmp_path, seeds["tiled"], 324, offset + shift))
    for shift in (1, 2):   # the one tile ends the file: moved on, it runs past the end
        with pytest.raises(DngError, match=r"bad.dng: .*(no SOI marker|file truncated)"):
            read_dng_pixels(mutated(tmp_path, seeds["tiled"], 324, offset + shift))


def test_decoded_raster_checks():
    mosaic = scene_mosaic()
    assert decoded_problem(mosaic, [64] * 4, 1023, RGGB) is None
    assert "shifted against its CFAPattern" in decoded_problem(np.roll(mosaic, 1, axis=1), [64] * 4, 1023, RGGB)
    assert "shifted against its CFAPattern" in decoded_problem(np.roll(mosaic, 1, axis=0), [64] * 4, 1023, RGGB)
    assert "are 0" in decoded_problem(np.where(np.arange(mosaic.size).reshape(mosaic.shape) > mosaic.size * 0.4,
                                               0, mosaic).astype(np.uint16), [64] * 4, 1023, RGGB)
    assert "every decoded pixel is 0" in decoded_problem(np.zeros_like(mosaic), [64] * 4, 1023, RGGB)
    shifted = np.concatenate([np.zeros(4, np.uint16), mosaic.ravel()[:-4]]).reshape(mosaic.shape)
    assert "starts with zeros" in decoded_problem(shifted, [64] * 4, 1023, RGGB)   # offsets 8 bytes early
    # what real files look like: pure noise around black (a dark frame), a saturated frame, a constant black frame
    dark = np.random.default_rng(1).normal(64, 2, mosaic.shape).round().astype(np.uint16)
    for fine in (dark, np.full_like(mosaic, 1023), np.full_like(mosaic, 64)):
        assert decoded_problem(fine, [64] * 4, 1023, RGGB) is None


def test_every_listed_mutation_is_refused_or_harmless(seeds, tmp_path):
    """The whole table of tests/fuzz_tags.py on both seeds: nothing silently corrupt, every
    refusal names the file, no error escapes as another type."""
    counts = collections.Counter()
    for kind in ("plain", "tiled"):
        truth = seeds["mosaic"]
        for index, (name, how, data) in enumerate(ft.mutations(seeds[kind].read_bytes())):
            path = tmp_path / f"{kind}_{index}.dng"
            path.write_bytes(data)
            result, message = ft.outcome(path, truth)
            counts[result] += 1
            assert result in ("refused", "pixels refused", "same pixels", "other size, same pixels"), \
                (kind, name, how, result, message)
            if result == "other size, same pixels":   # only a tiled file's size moved within its tiles
                assert kind == "tiled" and name in ("ImageWidth", "ImageLength"), (name, how)
    assert counts["refused"] > 50 and counts["pixels refused"] > 20, counts


def test_inputs_are_not_modified(seeds, tmp_path):
    path = mutated(tmp_path, seeds["plain"], 258, 8)
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    with pytest.raises(DngError):
        read_dng_info(path)
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before


@pytest.mark.data
@needs_gopro
def test_real_gopro_dng_with_lying_tags_is_refused(tmp_path):
    data = GOPRO.read_bytes()
    entries = ft.raw_entries(data)
    width, offset = ft.current(data, entries, 256), ft.current(data, entries, 273)
    for code, value, problem in ((258, 8, "bytes"), (258, 12, "bytes"), (258, 0, "BitsPerSample 0"),
                                 (258, 1, "bytes"), (256, width - 1, "(bytes|ActiveArea)"), (273, 0, "TIFF header"),
                                 (273, offset - 8, "lies on the value of tag")):   # onto the GPS IFD's values
        path = tmp_path / "gopro_bad.dng"
        path.write_bytes(ft.with_value(data, entries, code, value))
        with pytest.raises(DngError, match=f"gopro_bad.dng: .*{problem}"):
            read_dng_pixels(path)
    assert read_dng_pixels(GOPRO).shape == (3000, 4000)


def test_the_audit_loader_leaves_out_each_corrupt_file_by_name(seeds, tmp_path):
    """g2r-diagnose reads its DNGs with `load_measured`: each corrupt file of issue 34's classes is
    left out with a line naming it, the good file is kept with its pixels."""
    from g2r_jax.audit.loading import load_measured

    data = seeds["plain"].read_bytes()
    entries = ft.raw_entries(data)
    width = ft.current(data, entries, 256)
    bad = []
    for code, value in ((258, 8), (258, 12), (258, 0), (258, 1), (256, width - 1), (273, 0)):
        bad.append(tmp_path / f"bad_{code}_{value}.dng")
        bad[-1].write_bytes(ft.with_value(data, entries, code, value))
    lines = []
    loaded = load_measured([seeds["plain"]] + bad, on_error=lines.append)
    assert len(loaded) == 1 and np.array_equal(loaded[0][0], seeds["mosaic"][:96, :128])
    assert len(lines) == len(bad) and all(path.name in line for path, line in zip(bad, lines))


@pytest.mark.slow
def test_fit_profile_names_each_corrupt_file_and_fits_the_good_ones(seeds, tmp_path):
    import fuzz_harness as fh
    from g2r_jax.cli.fit_profile import main as fit_main

    data = seeds["plain"].read_bytes()
    entries = ft.raw_entries(data)
    folder = tmp_path / "in"
    folder.mkdir()
    for k in range(2):
        (folder / f"good{k}.dng").write_bytes(data)
    for code, value in ((258, 8), (256, ft.current(data, entries, 256) - 1), (273, 0)):
        (folder / f"bad_{code}.dng").write_bytes(ft.with_value(data, entries, code, value))
    status, _, err = fh.run_main(fit_main, [str(folder), "-o", str(tmp_path / "p.json")])
    assert status == 1 and (tmp_path / "p.json").exists()
    for code in (258, 256, 273):
        assert f"bad_{code}.dng" in err
    assert "Traceback" not in err
