"""Images whose header lies about their size: refused by name, memory bounded by the real data,
a pixel budget of our own (g2r_jax.io.image_headers, g2r_jax.io.images)."""

from __future__ import annotations

import struct
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from g2r_jax.io import image_headers
from g2r_jax.io.dng_info import DngError
from g2r_jax.io.images import read_image, read_image_uint8

ROOT = Path(__file__).resolve().parents[1]


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def lying_png(path: Path, width: int, height: int, rows: int, interlace: int = 0) -> Path:
    """An 8-bit RGB PNG whose IHDR claims width x height but whose data holds `rows` rows."""
    raw = b"".join(b"\0" + bytes(3 * width) for _ in range(rows))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, interlace)
    path.write_bytes(image_headers.PNG_SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(raw, 9))
                     + _chunk(b"IEND", b""))
    return path


def adam7_png(path: Path, pixels: np.ndarray) -> Path:
    """An interlaced (Adam7) 8-bit RGB PNG of `pixels`, written pass by pass (PNG spec 8.2)."""
    height, width, _ = pixels.shape
    raw = b""
    for x0, y0, dx, dy in image_headers._ADAM7:
        sub = pixels[y0::dy, x0::dx]
        if sub.size:
            raw += b"".join(b"\0" + row.tobytes() for row in sub)
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 1)
    path.write_bytes(image_headers.PNG_SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(raw))
                     + _chunk(b"IEND", b""))
    return path


def test_a_png_claiming_8000x8000_with_10_rows_is_refused_as_truncated(tmp_path):
    path = lying_png(tmp_path / "liar.png", 8000, 8000, 10)
    assert path.stat().st_size < 400
    with pytest.raises(DngError, match=r"liar\.png: truncated: the image data holds 10 of the 8000 rows"):
        read_image_uint8(path)


@pytest.mark.parametrize("mode", ["L", "LA", "RGB", "RGBA", "P", "1", "I;16"])
def test_complete_pngs_pass_the_check_and_decode(tmp_path, mode):
    pixels = np.random.default_rng(1).integers(0, 255, (37, 53, 3), dtype=np.uint8)
    image = Image.fromarray(pixels).convert(mode) if mode != "I;16" else \
        Image.fromarray(pixels[..., 0].astype(np.uint16) * 257)
    image.save(tmp_path / "ok.png")
    assert image_headers.check_png_complete(tmp_path / "ok.png") == (53, 37)
    assert read_image(tmp_path / "ok.png")[0].shape == (37, 53, 3)


@pytest.mark.parametrize("height, width", [(37, 53), (1, 1), (3, 9), (16, 16)])
def test_interlaced_pngs_are_measured_pass_by_pass(tmp_path, height, width):
    pixels = np.random.default_rng(0).integers(0, 255, (height, width, 3), dtype=np.uint8)
    path = adam7_png(tmp_path / "adam7.png", pixels)
    assert image_headers.check_png_complete(path) == (width, height)
    np.testing.assert_array_equal(read_image_uint8(path), pixels)
    empty = lying_png(tmp_path / "empty.png", width, height, 0, interlace=1)
    with pytest.raises(DngError, match=r"truncated: the image data holds 0\.0% of the"):
        image_headers.check_png_complete(empty)


def test_a_png_cut_in_its_data_is_refused(tmp_path):
    Image.fromarray(np.random.default_rng(2).integers(0, 255, (64, 80, 3), dtype=np.uint8)).save(tmp_path / "a.png")
    data = (tmp_path / "a.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(DngError, match=r"cut\.png: truncated"):
        read_image(tmp_path / "cut.png")


def test_the_pixel_budget_is_ours_and_named(tmp_path):
    path = lying_png(tmp_path / "big.png", 12000, 12000, 1)     # the budget is checked first, on the header alone
    with pytest.raises(DngError, match=r"big\.png: 12000x12000 is 144\.0 megapixels, over the budget of 100"):
        read_image(path)
    small = lying_png(tmp_path / "small.png", 64, 48, 48)
    with pytest.raises(DngError, match="over the budget"):
        read_image(small, max_pixels=1000)
    assert read_image(small, max_pixels=None)[0].shape == (48, 64, 3)


@pytest.mark.parametrize("suffix", [".jpg", ".tif"])
def test_the_budget_applies_to_jpeg_and_tiff_before_decoding(tmp_path, suffix):
    path = tmp_path / f"a{suffix}"
    Image.fromarray(np.zeros((40, 50, 3), np.uint8)).save(path)
    with pytest.raises(DngError, match=r"50x40 is 0\.0 megapixels, over the budget"):
        read_image(path, max_pixels=1999)
    assert read_image(path, max_pixels=2000)[0].shape == (40, 50, 3)


def test_a_jpeg_claiming_a_huge_frame_never_shows_pillows_words(tmp_path):
    path = tmp_path / "huge.jpg"
    Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(path)
    data = bytearray(path.read_bytes())
    sof = data.index(b"\xff\xc0")
    data[sof + 5: sof + 9] = struct.pack(">HH", 60000, 60000)
    path.write_bytes(bytes(data))
    with pytest.raises(DngError) as caught:
        read_image(path)
    assert "over the budget" in str(caught.value) and "ecompression" not in str(caught.value)


def test_a_jpeg_too_small_for_its_frame_is_refused_as_truncated(tmp_path):
    path = tmp_path / "liar.jpg"
    Image.fromarray(np.zeros((16, 24, 3), np.uint8)).save(path)
    data = bytearray(path.read_bytes())
    sof = data.index(b"\xff\xc0")
    data[sof + 5: sof + 9] = struct.pack(">HH", 8000, 8000)
    path.write_bytes(bytes(data))
    with pytest.raises(DngError, match=r"liar\.jpg: truncated: a 8000x8000 JPEG needs at least \d+ bytes"):
        read_image(path)
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)).save(path, quality=5)
    assert read_image(path)[0].shape == (480, 640, 3)
    Image.fromarray(np.zeros((480, 640, 3), np.uint8)).save(path, quality=5, progressive=True, subsampling=2)
    assert read_image(path)[0].shape == (480, 640, 3)     # flat, progressive, 4:2:0: smallest real files pass


def test_a_truncated_uncompressed_tiff_is_refused(tmp_path):
    Image.fromarray(np.zeros((64, 64, 3), np.uint8)).save(tmp_path / "a.tif")
    data = (tmp_path / "a.tif").read_bytes()
    (tmp_path / "cut.tif").write_bytes(data[:-5000])
    with pytest.raises(DngError, match=r"cut\.tif: truncated"):
        read_image(tmp_path / "cut.tif")


def test_converting_the_lying_png_is_refused_by_name_in_bounded_memory(tmp_path):
    """The whole command, in a subprocess whose own peak resident memory is measured (fresh_process)."""
    folder = tmp_path / "in"
    folder.mkdir()
    lying_png(folder / "liar.png", 8000, 8000, 10)
    from fresh_process import run_measured

    result, peak_gib = run_measured([sys.executable, "-m", "g2r_jax.cli.convert", str(folder), "--profile", "NikonD40",
                                     "-o", str(tmp_path / "out")], cwd=ROOT, capture_output=True, text=True)
    stderr = result.stderr
    assert "liar.png: truncated: the image data holds 10 of the 8000 rows" in stderr
    assert "ecompression" not in stderr
    assert not list((tmp_path / "out").glob("*.dng"))
    assert peak_gib < 1.0, f"peak resident memory {peak_gib:.2f} GiB"


def test_a_png_whose_data_is_plausible_but_short_is_refused_with_its_rows(tmp_path):
    """Below the plausible compression ratio the fast decoder runs without counting first: it must
    refuse the missing rows too, and the message must still say how many there are."""
    from g2r_jax.io import images

    noise = np.random.default_rng(4).integers(0, 256, (150, 300 * 3), dtype=np.uint8)
    raw = b"".join(b"\0" + row.tobytes() for row in noise)
    header = struct.pack(">IIBBBBB", 300, 200, 8, 2, 0, 0, 0)
    path = tmp_path / "short.png"
    path.write_bytes(image_headers.PNG_SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(raw))
                     + _chunk(b"IEND", b""))
    _, _, _, _, claimed, present = image_headers.png_claim(path, path.read_bytes())
    assert claimed < images.PLAUSIBLE_PNG_RATIO * present          # so the counting route is not taken first
    with pytest.raises(DngError, match=r"short\.png: truncated: the image data holds 150 of the 200 rows"):
        read_image_uint8(path)
