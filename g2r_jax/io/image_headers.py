"""What an image file claims before it is decoded: its size from the header, checked against a
pixel budget, and for PNG whether the compressed data really holds that many rows.

A header can claim any size: a 312-byte PNG may declare 8000x8000 pixels and carry ten rows.
Decoders allocate for the claim and fill the missing rows with zeros, silently. Here the claim is
read without decoding, refused above the budget (`check_pixel_budget`), and a
PNG's zlib stream is inflated in small pieces, counting bytes without keeping them
(`check_png_complete`), so memory stays bounded by the file's real data, not by its claim; a
JPEG must at least be large enough to code one bit per 8x8 block (`check_jpeg_complete`).
Formats: PNG (ISO/IEC 15948, IHDR and IDAT chunks), JPEG (ITU T.81 B.2.2, the SOF segment),
TIFF (through tifffile's page shape), OpenEXR (the dataWindow of the header).
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

from g2r_jax.io.dng_info import DngError

__all__ = ["DEFAULT_MAX_PIXELS", "PNG_SIGNATURE", "check_pixel_budget", "check_png_complete",
           "check_jpeg_complete", "png_claim"]

DEFAULT_MAX_PIXELS = 100_000_000      # 100 megapixels per image: 1.2 GB as float32 RGB
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}      # colour type -> samples per pixel
_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
_JPEG_HUFFMAN = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7}
_PIECE = 1 << 20                      # bytes read and inflated at a time


def _png_header(path: Path, handle) -> tuple:
    """(width, height, bit depth, colour type, interlace) from IHDR; DngError when malformed."""
    head = handle.read(33)
    if len(head) < 33 or head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise DngError(path, "not a PNG or its header is damaged (no IHDR chunk)")
    width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", head[16:29])
    if colour not in _PNG_CHANNELS or depth not in (1, 2, 4, 8, 16) or interlace not in (0, 1):
        raise DngError(path, f"PNG header is damaged (bit depth {depth}, colour type {colour})")
    return width, height, depth, colour, interlace


def _jpeg_size(path: Path, handle) -> tuple:
    """(width, height, SOF marker, [(H, V) per component]) from the first SOF segment (T.81
    B.2.2); DngError when none is found."""
    if handle.read(2) != b"\xff\xd8":
        raise DngError(path, "not a JPEG (no start-of-image marker)")
    while True:
        marker = handle.read(2)
        while len(marker) == 2 and marker[0] == 0xFF and marker[1] == 0xFF:   # fill bytes
            marker = marker[1:] + handle.read(1)
        if len(marker) < 2 or marker[0] != 0xFF:
            raise DngError(path, "JPEG is truncated or damaged before its frame header")
        if 0xD0 <= marker[1] <= 0xD9 or marker[1] == 0x01:   # markers without a length
            continue
        length = handle.read(2)
        if len(length) < 2 or struct.unpack(">H", length)[0] < 2:
            raise DngError(path, "JPEG is truncated or damaged before its frame header")
        size = struct.unpack(">H", length)[0] - 2
        if marker[1] in _JPEG_SOF:
            frame = handle.read(size)
            if len(frame) < 6 or len(frame) < 6 + 3 * frame[5]:
                raise DngError(path, "JPEG frame header is truncated")
            height, width = struct.unpack(">HH", frame[1:5])
            sampling = [(frame[7 + 3 * c] >> 4, frame[7 + 3 * c] & 15) for c in range(frame[5])]
            return width, height, marker[1], sampling
        handle.seek(size, 1)


def _jpeg_minimum_bytes(width: int, height: int, sampling) -> int:
    """A lower bound of a Huffman-coded JPEG's size: every 8x8 block of every component codes at
    least its DC difference, one bit at the least (T.81 F.1.2.1; progressive: G.1.2.1)."""
    h_max = max(max(h for h, _ in sampling), 1)
    v_max = max(max(v for _, v in sampling), 1)
    blocks = 0
    for h, v in sampling:
        columns = -(-width * max(h, 1) // h_max)
        rows = -(-height * max(v, 1) // v_max)
        blocks += -(-columns // 8) * -(-rows // 8)
    return blocks // 8


def check_jpeg_complete(path, max_pixels: int | None = DEFAULT_MAX_PIXELS) -> tuple:
    """Refuse a JPEG larger than the budget, or too small a file to hold the frame its header
    claims (decoders fill the missing blocks with grey, silently).

    **Arguments:** `path`: a JPEG file; `max_pixels`: the budget (None: none).

    **Returns:** (width, height). Raises `DngError` naming the file. Arithmetic-coded JPEGs, which
    may spend less than a bit on a block, are only checked against the budget.
    """
    path = Path(path)
    with open(path, "rb") as handle:
        width, height, marker, sampling = _jpeg_size(path, handle)
    check_pixel_budget(path, width, height, max_pixels)
    if marker in _JPEG_HUFFMAN:
        needed, size = _jpeg_minimum_bytes(width, height, sampling), path.stat().st_size
        if size < needed:
            raise DngError(path, f"truncated: a {width}x{height} JPEG needs at least {needed} bytes of image data, "
                                 f"the file has {size}")
    return width, height


def check_pixel_budget(path, width: int, height: int, max_pixels: int | None) -> None:
    """Refuse an image larger than `max_pixels` (None: no budget) with a line naming the file."""
    if width < 1 or height < 1:
        raise DngError(path, f"header claims an empty image ({width}x{height})")
    if max_pixels is not None and width * height > max_pixels:
        raise DngError(path, f"{width}x{height} is {width * height / 1e6:.1f} megapixels, over the budget of "
                             f"{max_pixels / 1e6:g} per image (--max-megapixels raises it)")


def _png_expected_bytes(width: int, height: int, depth: int, colour: int, interlace: int) -> int:
    """Bytes of the filtered image data: one filter byte per row plus the packed samples
    (PNG spec 2nd ed. 7.2, 8.2 for the Adam7 passes)."""
    bits = depth * _PNG_CHANNELS[colour]
    if not interlace:
        return height * (1 + (width * bits + 7) // 8)
    total = 0
    for x0, y0, dx, dy in _ADAM7:
        pass_width = (width - x0 + dx - 1) // dx if width > x0 else 0
        pass_height = (height - y0 + dy - 1) // dy if height > y0 else 0
        if pass_width and pass_height:
            total += pass_height * (1 + (pass_width * bits + 7) // 8)
    return total


def png_claim(path, data: bytes | None = None) -> tuple:
    """(width, height, bit depth, colour type, filtered bytes the header claims, compressed IDAT
    bytes present) of a PNG, from its chunk headers only (no inflating): from `data` when given
    (the file already read), else from the file, seeking past each chunk's content. DngError
    when it has no valid IHDR."""
    import io

    with (io.BytesIO(data) if data is not None else open(path, "rb")) as handle:
        width, height, depth, colour, interlace = _png_header(Path(path), handle)
        size = handle.seek(0, io.SEEK_END)
        present, at = 0, 8
        while at + 8 <= size:
            handle.seek(at)
            length, kind = struct.unpack(">I4s", handle.read(8))
            if kind == b"IDAT":
                present += min(length, size - at - 8)
            elif kind == b"IEND":
                break
            at += 12 + length
    return width, height, depth, colour, _png_expected_bytes(width, height, depth, colour, interlace), present


def check_png_complete(path, max_pixels: int | None = DEFAULT_MAX_PIXELS) -> tuple:
    """Refuse a PNG larger than the budget, or whose image data holds fewer bytes than its
    header's size needs.

    The IDAT chunks are inflated a piece at a time and only counted: memory is bounded by
    `_PIECE`, whatever size the header claims.

    **Arguments:** `path`: a PNG file; `max_pixels`: the budget (None: none).

    **Returns:** (width, height). Raises `DngError` naming the file: truncated (with the rows
    present), or a damaged compressed stream.
    """
    path = Path(path)
    with open(path, "rb") as handle:
        width, height, depth, colour, interlace = _png_header(path, handle)
        check_pixel_budget(path, width, height, max_pixels)
        expected = _png_expected_bytes(width, height, depth, colour, interlace)
        handle.seek(8)
        inflater, produced = zlib.decompressobj(), 0
        while produced < expected and not inflater.eof:
            head = handle.read(8)
            if len(head) < 8:
                break
            length, kind = struct.unpack(">I4s", head)
            if kind == b"IEND":
                break
            if kind != b"IDAT":
                handle.seek(length + 4, 1)
                continue
            remaining = length
            while remaining and produced < expected and not inflater.eof:
                data = handle.read(min(_PIECE, remaining))
                if not data:
                    break
                remaining -= len(data)
                try:
                    produced += len(inflater.decompress(data, _PIECE))
                    while inflater.unconsumed_tail and produced < expected:
                        produced += len(inflater.decompress(inflater.unconsumed_tail, _PIECE))
                except zlib.error:
                    raise DngError(path, "PNG image data is damaged (its compressed stream does not inflate)") from None
            handle.seek(remaining + 4, 1)
    if produced < expected:
        if interlace:
            raise DngError(path, f"truncated: the image data holds {100 * produced / expected:.1f}% of the "
                                 f"{width}x{height} pixels its header claims")
        rows = produced // (1 + (width * depth * _PNG_CHANNELS[colour] + 7) // 8)
        raise DngError(path, f"truncated: the image data holds {rows} of the {height} rows its header claims "
                             f"({width}x{height})")
    return width, height
