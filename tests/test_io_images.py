"""CG image decoding (PNG, JPEG, TIFF, EXR) and input listing."""

from __future__ import annotations

import hashlib
import struct
import zlib
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
import tifffile
from PIL import Image

from g2r_jax.io.dng_info import DngError
from g2r_jax.io.images import list_inputs, read_image, read_image_uint8, read_images


def hashes(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file()}


def write_png(path: Path, samples: np.ndarray, bitdepth: int):
    """A PNG using all five row filters in turn (PNG spec section 9), so decoders' unfiltering is exercised."""
    h, w, c = samples.shape
    dtype = ">u2" if bitdepth == 16 else "u1"
    bpp = c * bitdepth // 8
    rows = np.ascontiguousarray(samples.astype(dtype)).view(np.uint8).reshape(h, w * bpp).astype(np.int64)
    lines = []
    for y in range(h):
        x = rows[y]
        up = rows[y - 1] if y else np.zeros_like(x)
        left = np.concatenate([np.zeros(bpp, np.int64), x[:-bpp]])
        upleft = np.concatenate([np.zeros(bpp, np.int64), up[:-bpp]])
        p = left + up - upleft
        pa, pb, pc = np.abs(p - left), np.abs(p - up), np.abs(p - upleft)
        paeth = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, up, upleft))
        kind = y % 5
        filtered = (x, x - left, x - up, x - (left + up) // 2, x - paeth)[kind] % 256
        lines.append(bytes([kind]) + filtered.astype(np.uint8).tobytes())

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    colour_type = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    path.write_bytes(b"\x89PNG\r\n\x1a\n"
                     + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bitdepth, colour_type, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(b"".join(lines)))
                     + chunk(b"IEND", b""))


def write_exr(path: Path, channels: dict):
    # the OpenEXR binding reads the raw buffer: channel arrays must be C-contiguous
    channels = {k: np.ascontiguousarray(v) for k, v in channels.items()}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as exr:
        exr.write(str(path))


RNG = np.random.default_rng(7)
U16 = RNG.integers(0, 65536, (23, 37, 4), dtype=np.uint16)     # odd sizes on purpose
U8 = RNG.integers(0, 256, (23, 37, 4), dtype=np.uint8)
F32 = RNG.random((23, 37, 3)).astype(np.float32) * 4


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_png_16bit_exact(tmp_path, channels):
    path = tmp_path / f"c{channels}.png"
    write_png(path, U16[:, :, :channels], 16)
    image, encoding = read_image(path)
    want = U16[:, :, :3] if channels >= 3 else np.repeat(U16[:, :, :1], 3, axis=2)
    assert encoding == "srgb" and image.dtype == np.float32 and image.shape == (23, 37, 3)
    np.testing.assert_array_equal(np.round(image * 65535).astype(np.uint16), want)
    assert read_image_uint8(path) is None


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_png_8bit_exact(tmp_path, channels):
    path = tmp_path / f"c{channels}.png"
    write_png(path, U8[:, :, :channels], 8)
    want = U8[:, :, :3] if channels >= 3 else np.repeat(U8[:, :, :1], 3, axis=2)
    raw = read_image_uint8(path)
    assert raw.dtype == np.uint8
    np.testing.assert_array_equal(raw, want)
    image, encoding = read_image(path)
    assert encoding == "srgb"
    np.testing.assert_allclose(image, want / 255.0, atol=1e-7)


def test_palette_png_and_jpeg(tmp_path):
    rgb = U8[:, :, :3]
    Image.fromarray(rgb).convert("P").save(tmp_path / "p.png")
    want = np.asarray(Image.open(tmp_path / "p.png").convert("RGB"))
    np.testing.assert_array_equal(read_image_uint8(tmp_path / "p.png"), want)
    smooth = np.repeat(np.linspace(0, 255, 37)[None, :, None], 23, axis=0).repeat(3, axis=2).astype(np.uint8)
    Image.fromarray(smooth).save(tmp_path / "s.JPG", quality=98)
    image, encoding = read_image(tmp_path / "s.JPG")
    assert encoding == "srgb" and image.shape == (23, 37, 3)
    assert np.abs(image * 255 - smooth).max() < 6
    Image.fromarray(smooth[:, :, 0]).save(tmp_path / "g.jpeg")
    assert read_image_uint8(tmp_path / "g.jpeg").shape == (23, 37, 3)


def test_tiff(tmp_path):
    tifffile.imwrite(tmp_path / "a.tif", U16[:, :, :3], photometric="rgb")
    tifffile.imwrite(tmp_path / "b.tiff", U8, photometric="rgb", extrasamples=["unassalpha"])
    tifffile.imwrite(tmp_path / "c.tif", np.moveaxis(U8[:, :, :3], -1, 0), photometric="rgb",
                     planarconfig="separate")
    tifffile.imwrite(tmp_path / "d.tif", U16[:, :, 0], photometric="minisblack")
    tifffile.imwrite(tmp_path / "e.tif", F32, photometric="rgb")
    image, encoding = read_image(tmp_path / "a.tif")
    assert encoding == "srgb"
    np.testing.assert_array_equal(np.round(image * 65535).astype(np.uint16), U16[:, :, :3])
    np.testing.assert_array_equal(read_image_uint8(tmp_path / "b.tiff"), U8[:, :, :3])
    np.testing.assert_array_equal(read_image_uint8(tmp_path / "c.tif"), U8[:, :, :3])
    grey, _ = read_image(tmp_path / "d.tif")
    np.testing.assert_array_equal(np.round(grey * 65535).astype(np.uint16), np.repeat(U16[:, :, :1], 3, axis=2))
    assert read_image_uint8(tmp_path / "d.tif") is None
    with pytest.raises(DngError, match="e.tif: floating-point"):
        read_image(tmp_path / "e.tif")
    # LZW needs imagecodecs in tifffile; 8-bit files then go through Pillow, losslessly
    Image.fromarray(U8[:, :, :3]).save(tmp_path / "lzw.tif", compression="tiff_lzw")
    np.testing.assert_array_equal(read_image_uint8(tmp_path / "lzw.tif"), U8[:, :, :3])


def test_exr(tmp_path):
    write_exr(tmp_path / "f.exr", {"R": F32[..., 0], "G": F32[..., 1], "B": F32[..., 2],
                                   "A": np.ones(F32.shape[:2], np.float32)})
    write_exr(tmp_path / "h.exr", {"RGB": F32.astype(np.float16)})
    write_exr(tmp_path / "layer.exr", {"beauty.R": F32[..., 0], "beauty.G": F32[..., 1], "beauty.B": F32[..., 2]})
    write_exr(tmp_path / "y.exr", {"Y": F32[..., 0]})
    image, encoding = read_image(tmp_path / "f.exr")
    assert encoding == "linear" and image.dtype == np.float32
    np.testing.assert_array_equal(image, F32)
    np.testing.assert_array_equal(read_image(tmp_path / "h.exr")[0], F32.astype(np.float16).astype(np.float32))
    np.testing.assert_array_equal(read_image(tmp_path / "layer.exr")[0], F32)
    np.testing.assert_array_equal(read_image(tmp_path / "y.exr")[0], np.repeat(F32[..., :1], 3, axis=2))
    assert read_image_uint8(tmp_path / "f.exr") is None


def test_exr_bad_values(tmp_path):
    bad = F32.copy()
    bad[0, 0, 0], bad[1, 2, 1], bad[3, 3, 2] = np.nan, np.inf, -np.inf
    write_exr(tmp_path / "nan.exr", {"RGB": bad})
    neg = F32.copy()
    neg[5, :7, 1] = -0.25
    write_exr(tmp_path / "neg.exr", {"RGB": neg})
    write_exr(tmp_path / "depth.exr", {"Z": F32[..., 0]})
    write_exr(tmp_path / "uint.exr", {c: (F32[..., 0] * 10).astype(np.uint32) for c in "RGB"})
    before = hashes(tmp_path)
    with pytest.raises(DngError, match=r"nan.exr: contains 3 NaN/Inf values"):
        read_image(tmp_path / "nan.exr")
    with pytest.raises(DngError, match=r"neg.exr: contains 7 negative values"):
        read_image(tmp_path / "neg.exr")
    with pytest.raises(DngError, match="no R, G, B channels"):
        read_image(tmp_path / "depth.exr")
    with pytest.raises(DngError, match="not half or float"):
        read_image(tmp_path / "uint.exr")
    assert hashes(tmp_path) == before


def test_damaged_files(tmp_path):
    write_png(tmp_path / "ok.png", U16[:, :, :3], 16)
    Image.fromarray(U8[:, :, :3]).save(tmp_path / "ok.jpg")
    write_exr(tmp_path / "ok.exr", {"RGB": F32})
    tifffile.imwrite(tmp_path / "ok.tif", U8[:, :, :3], photometric="rgb")
    cases = {
        "text.png": b"just some text\n" * 20,
        "text.exr": b"just some text\n" * 20,
        "text.tif": b"just some text\n" * 20,
        "cut.png": (tmp_path / "ok.png").read_bytes()[:400],
        "cut.jpg": (tmp_path / "ok.jpg").read_bytes()[:600],
        "cut.exr": (tmp_path / "ok.exr").read_bytes()[:60],
        "cut.tif": (tmp_path / "ok.tif").read_bytes()[:300],
    }
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
    (tmp_path / "x.bmp").write_bytes(b"BM")
    before = hashes(tmp_path)
    for name in cases:
        with pytest.raises(DngError, match=name.replace(".", r"\.")):
            read_image(tmp_path / name)
    with pytest.raises(DngError, match="file not found"):
        read_image(tmp_path / "missing.png")
    with pytest.raises(DngError, match="unsupported image type"):
        read_image(tmp_path / "x.bmp")
    assert hashes(tmp_path) == before


def test_list_inputs(tmp_path):
    folder = tmp_path / "renders"
    folder.mkdir()
    for name in ("b.png", "A.EXR", "c.jpg", ".hidden.png", "notes.txt"):
        (folder / name).write_bytes(b"x")
    (folder / "sub").mkdir()
    (folder / "sub" / "d.png").write_bytes(b"x")
    got = list_inputs(folder, (".png", ".exr", "jpg"))
    assert [p.name for p in got] == ["A.EXR", "b.png", "c.jpg"]
    assert [p.name for p in list_inputs([str(folder / "c.jpg"), folder], [".png", ".jpg"])] == ["c.jpg", "b.png"]
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DngError, match="empty: folder has no input files"):
        list_inputs([empty], [".png"])
    with pytest.raises(DngError, match="no input files"):
        list_inputs(folder, [".tif"])
    with pytest.raises(DngError, match="no such file or folder"):
        list_inputs([tmp_path / "nope"], [".png"])
    with pytest.raises(DngError, match="unsupported file type"):
        list_inputs([folder / "notes.txt"], [".png"])


@pytest.mark.parametrize("mode", ["1", "L", "P", "RGB", "RGBA", "LA", "grey4", "palette-transparent"])
def test_the_fast_png_decoder_gives_pillows_pixels(tmp_path, mode):
    """8-bit PNGs go through libspng, others through Pillow: the pixels must be the same."""
    from g2r_jax.io import images

    rgb = U8[:, :, :3]
    path = tmp_path / "a.png"
    if mode == "grey4":
        Image.fromarray(rgb[:, :, 0] // 17 * 17).save(path, bits=4)
    elif mode == "palette-transparent":
        Image.fromarray(rgb).convert("P").save(path, transparency=3)
    else:
        Image.fromarray(rgb).convert(mode).save(path)
    fast, bits = images._read_integer(path, ".png")
    reference, reference_bits = images._read_pillow(path)
    assert bits == reference_bits == 8 and fast.dtype == reference.dtype == np.uint8
    np.testing.assert_array_equal(fast, reference)


def test_a_png_with_more_data_than_rows_decodes_silently(tmp_path, capfd):
    """libpng would print 'Too much image data' on stderr; nothing of a library reaches the user."""
    rows = b"".join(b"\0" + U8[i % 23, :, :3].tobytes() for i in range(30))
    header = struct.pack(">IIBBBBB", 37, 23, 8, 2, 0, 0, 0)
    chunk = lambda kind, data: struct.pack(">I", len(data)) + kind + data + struct.pack(
        ">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    path = tmp_path / "long.png"
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows))
                     + chunk(b"IEND", b""))
    np.testing.assert_array_equal(read_image_uint8(path), U8[:, :, :3])
    assert capfd.readouterr().err == ""


def test_read_images_names_and_skips_bad_files(tmp_path):
    """The one CG loader (`read_images`): every readable image in input order; a damaged file and
    one under `min_side` go to `problem` by name and the rest are read; without `problem` they raise."""
    good = np.random.default_rng(0).integers(0, 256, (20, 24, 3)).astype(np.uint8)
    Image.fromarray(good).save(tmp_path / "a_good.png")
    (tmp_path / "b_damaged.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40)
    Image.fromarray(good[:8]).save(tmp_path / "c_small.png")
    problems = []
    found = read_images(tmp_path, min_side=16, problem=lambda path, why: problems.append((Path(path).name, why)))
    assert [p.name for p, _, _ in found] == ["a_good.png"]
    assert np.array_equal(np.round(found[0][1] * 255).astype(np.uint8), good) and found[0][2] == "srgb"
    assert [name for name, _ in problems] == ["b_damaged.png", "c_small.png"]
    assert "smaller than 16" in problems[1][1]
    with pytest.raises(DngError, match="b_damaged"):
        read_images(tmp_path)
