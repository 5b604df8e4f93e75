"""Lossless JPEG DNGs (`compression='ljpeg'`): the same pixels through LibRaw, the Adobe DNG SDK
(dngpy), tifffile and our reader, for edge tiles, narrow images and every precision."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import rawpy
import tifffile

from g2r_jax.io.dng_info import DngError
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
from g2r_jax.io.dng_write import write_dng, write_dng_bytes
from g2r_jax.io.lossless_jpeg import encode_tiles, precision_for, tile_shape
from test_io_dng import make_info

# (height, width, white level): edge tiles both ways, images narrower and shorter than a tile,
# LibRaw's smallest accepted size, 8 to 16 bits
CASES = [(300, 530, 1023), (32, 48, 1023), (22, 22, 255), (64, 250, 16383), (258, 272, 65535), (40, 530, 4095)]


def smooth_mosaic(height, width, white, seed=0) -> np.ndarray:
    """A Bayer-like mosaic: a smooth ramp per colour plus noise, clipped to [0, white]."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width]
    base = white * (0.2 + 0.6 * (x / width) * (0.5 + 0.5 * (y % 2)) + 0.1 * (x % 2))
    return np.clip(base + rng.normal(0, 0.01 * white, base.shape), 0, white).astype(np.uint16)


def write_pair(tmp_path, height, width, white):
    mosaic = smooth_mosaic(height, width, white)
    mosaic[0, 0], mosaic[-1, -1] = 0, white          # both ends of the range in every file
    info = make_info(white_level=float(white), black_level=np.zeros(4), opcode_lists={})
    paths = {}
    for compression in ("none", "ljpeg"):
        paths[compression] = tmp_path / f"{height}x{width}_{compression}.dng"
        write_dng(paths[compression], mosaic, info, compression=compression)
    return mosaic, paths


@pytest.mark.parametrize("height,width,white", CASES)
def test_ljpeg_pixels_equal_in_every_reader(tmp_path, height, width, white):
    mosaic, paths = write_pair(tmp_path, height, width, white)
    path = paths["ljpeg"]
    with tifffile.TiffFile(path) as tif:
        page = tif.pages[0]
        assert page.compression == 7 and page.is_tiled and page.bitspersample == 16
        assert page.tilewidth <= width                    # LibRaw scrambles tiles wider than the image
        np.testing.assert_array_equal(page.asarray(), mosaic)
    with rawpy.imread(str(path)) as raw:
        np.testing.assert_array_equal(raw.raw_image, mosaic)
    np.testing.assert_array_equal(read_dng_pixels(path), mosaic)
    # the tags are those of the uncompressed file
    plain, packed = read_dng_info(paths["none"]), read_dng_info(path)
    assert plain.white_level == packed.white_level and plain.cfa_pattern == packed.cfa_pattern
    np.testing.assert_array_equal(plain.color_matrices[0], packed.color_matrices[0])


@pytest.mark.parametrize("height,width,white", CASES)
def test_ljpeg_pixels_equal_in_adobe_sdk(tmp_path, height, width, white):
    dngpy = pytest.importorskip("dngpy")
    mosaic, paths = write_pair(tmp_path, height, width, white)
    for path in paths.values():
        pixels = dngpy.Dng(str(path)).raw_pixels
        np.testing.assert_array_equal(pixels.reshape(mosaic.shape), mosaic)


def test_ljpeg_is_smaller_and_deterministic(tmp_path):
    mosaic = smooth_mosaic(512, 768, 1023)
    info = make_info(opcode_lists={})
    packed = write_dng_bytes(mosaic, info, compression="ljpeg")
    assert packed == write_dng_bytes(mosaic.copy(), info, compression="ljpeg")
    assert len(packed) < 0.6 * len(write_dng_bytes(mosaic, info))


def test_row_pair_layout_beats_plain_rows():
    """Two mosaic rows per JPEG row put a same-colour sample above each one (see the module doc)."""
    import imagecodecs

    mosaic = smooth_mosaic(256, 256, 1023)
    row_pairs = sum(map(len, encode_tiles(mosaic, 10)))
    plain = len(imagecodecs.ljpeg_encode(mosaic, bitspersample=10))
    assert row_pairs < 0.95 * plain


def test_precision_and_tile_shape():
    assert precision_for(np.zeros((2, 2), np.uint16), 1023) == 10
    assert precision_for(np.zeros((2, 2), np.uint16), 16383) == 14
    assert precision_for(np.zeros((2, 2), np.uint16), 255) == 8
    assert precision_for(np.full((2, 2), 2000, np.uint16), 1023) == 11   # values above white still fit
    assert precision_for(np.zeros((2, 2), np.uint16), 100) == 8          # liblj92's smallest
    assert tile_shape(3024, 4032) == (256, 256)
    assert tile_shape(30, 46) == (32, 32)
    assert tile_shape(300, 250) == (256, 240)
    with pytest.raises(ValueError, match="multiples of 16"):
        encode_tiles(np.zeros((32, 32), np.uint16), 8, (24, 32))


def test_unknown_compression_is_refused(tmp_path):
    with pytest.raises(DngError, match="unknown compression 'zip'"):
        write_dng_bytes(smooth_mosaic(32, 48, 1023), make_info(), compression="zip")


@pytest.mark.slow
def test_convert_ljpeg_gives_the_uncompressed_pixels(tmp_path):
    from PIL import Image

    from g2r_jax.batch.conversion import ConvertOptions, convert_files
    from g2r_jax.profile.schema import load_profile

    rng = np.random.default_rng(3)
    source = tmp_path / "in" / "frame.png"
    source.parent.mkdir()
    Image.fromarray(rng.integers(0, 256, (96, 160, 3), dtype=np.uint8)).save(source)
    profile = load_profile("s20fe_night")
    outputs = {}
    for compression in ("none", "ljpeg"):
        options = ConvertOptions(progress=False, compression=compression, batch_size=1)
        result = convert_files([source], profile, tmp_path / compression, options=options)
        assert result.ok, result.errors
        outputs[compression] = tmp_path / compression / "frame.dng"
    np.testing.assert_array_equal(read_dng_pixels(outputs["ljpeg"]), read_dng_pixels(outputs["none"]))
    assert outputs["ljpeg"].stat().st_size < outputs["none"].stat().st_size
    with pytest.raises(ValueError, match="unknown DNG compression"):
        convert_files([source], profile, tmp_path / "bad", options=dataclasses.replace(options, compression="zip"))


def test_identity_effects_are_recognised():
    import jax.numpy as jnp

    from g2r_jax.sensor.effects import changes_nothing, no_effects

    assert changes_nothing(no_effects())
    for field, value in [("black_pedestal", jnp.ones(4)), ("clip_level", jnp.asarray(0.9)),
                         ("channel_gain", jnp.asarray([1.0, 1.02, 1.0, 1.0])), ("shading", jnp.full((4, 2), -0.1)),
                         ("row_noise_std", jnp.asarray(1e-3)), ("column_noise_std", jnp.asarray(1e-3)),
                         ("defect_rows", jnp.asarray([3], jnp.int32))]:
        assert not changes_nothing(dataclasses.replace(no_effects(), **{field: value})), field


@pytest.mark.slow
def test_skipping_identity_effects_keeps_the_bytes():
    """`convert_files` compiles without the effects of a profile whose effects change nothing:
    the mosaics are those with the effects rendered (profile traced, as conversion passes it)."""
    import jax

    from g2r_jax.pipeline import unprocess_batch
    from g2r_jax.profile.schema import load_profile
    from g2r_jax.sensor.effects import changes_nothing

    for name in ("Canon600D", "gopro_hero6"):
        profile = load_profile(name)
        assert changes_nothing(profile.effects)
        images = np.random.default_rng(1).integers(0, 256, (2, 64, 96, 3), dtype=np.uint8)
        keys = jax.random.split(jax.random.PRNGKey(7), 2)
        run = lambda effects: np.asarray(jax.jit(lambda k, im, p: unprocess_batch(k, im, p, effects=effects)[0])(
            keys, images, profile))
        np.testing.assert_array_equal(run(True), run(False))
