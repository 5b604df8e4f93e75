"""Does a DNG's raw pixel data agree with the tags that describe it?

LibRaw decodes whatever bytes the tags point at: with BitsPerSample 8 on 16-bit data, an
ImageWidth one column short or StripOffsets 0 it returns a raster of garbage without a word
(issue 34). These checks compare the raw IFD's layout tags with each other and with the file
before any pixel is decoded, and the decoded raster with the levels the tags promise after.

Layout rules: TIFF 6.0 (Adobe, 1992) section 3 (StripOffsets, StripByteCounts, RowsPerStrip:
"StripsPerImage = floor((ImageLength + RowsPerStrip - 1) / RowsPerStrip)"; rows of uncompressed
data padded to a whole byte) and section 15 (TileOffsets, TileByteCounts: tiles cover the image,
padded tiles included, "TilesPerImage = TilesAcross * TilesDown"); DNG specification 1.6 ch. 4
'BitsPerSample' (1..32 bits), 'WhiteLevel' (default 2 ** BitsPerSample - 1, so a level above that
cannot be stored) and ch. 3 'Compression' (lossless JPEG, ITU T.81 Annex H: the stream's frame
header, SOF3, gives its sample precision and size).

Two kinds of finding:
- a *refusal* (`LayoutProblem.refusal`): the tags contradict the data or each other (byte counts
  that do not match width x rows x bits, a segment on top of the file's header or tags, a
  BitsPerSample that cannot hold the WhiteLevel); the file's tags cannot be trusted, the reader
  raises;
- a *warning* (`LayoutProblem.warning`): pixel data missing or cut short, the tags themselves
  consistent (e.g. a header-only DNG); the tags stay usable, pixel decoding is refused.
A decoded raster (`decoded_finding`) gives a refusal, or a warning when only part of the evidence
that its green sites are out of phase holds (the pixels are then used as tagged).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Optional

import numpy as np

__all__ = ["LayoutProblem", "layout_problem", "stored_values_problem", "bits_problem", "decoded_problem",
           "decoded_finding", "MAX_SHARE_ABOVE_WHITE", "FAR_ABOVE_WHITE", "ZERO_FILL_SHARE", "ZERO_FILL_MIN_BLACK",
           "GREEN_PHASE_RATIO", "GREEN_SHARED_RATIO", "GREEN_DISTRIBUTION_RATIO", "GREEN_SPLIT_SHARE"]

_OFFSET_TAGS = {"strips": (273, 279), "tiles": (324, 325)}   # (offsets, byte counts)
_HEADER_BYTES = 8            # TIFF header: byte order, 42, offset of IFD0
_IFD_ENTRY_BYTES = 12
_POINTER_TAGS = (34665, 34853)   # ExifIFD, GPSInfo: offsets of IFDs of their own
_TYPE_BYTES = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 6: 1, 7: 1, 8: 2, 9: 4, 10: 8, 11: 4, 12: 8, 13: 4}   # TIFF 6.0 section 2
_LOSSLESS_JPEG = 7
_UNCOMPRESSED = 1
_PHOTOMETRIC_CFA = 32803
_TOKEN_BYTES = 65536           # pixel data this large is there: its size must fit the tags
MAX_SHARE_ABOVE_WHITE = 0.01   # share of values allowed far above WhiteLevel (hot pixels)
FAR_ABOVE_WHITE = 1.5          # "far above": over 1.5 x WhiteLevel. Some cameras tag the end of the
                               # linear range and their highlights run past it, never this far
ZERO_FILL_SHARE = 0.5          # LibRaw fills data it cannot find with zeros
ZERO_FILL_MIN_BLACK = 16.0     # below this black level, zeros can be real dark pixels
# The green-phase check (`_green_phase_finding`, issue 44). Measured on 1,920 valid rasters (10 kinds of CG
# content converted with 6 shipped profiles, each rewritten in the 4 CFA phases), the three
# `g2r-convert --example` files and the real GoPro HERO6 frame, and each of them shifted by one
# pixel and by one row, both ways (benchmarks/valid_reader.py makes the same kinds: 5,281 valid files,
# 0 refused):
GREEN_PHASE_RATIO = 1.5        # tagged greens' gap / their own diagonal step: valid files at most 1.08 (lines
                               # 1-2 px wide aside), the shifted examples and GoPro 3.9-5.5
GREEN_SHARED_RATIO = 0.9       # the other pair's gap / its step: content that is noise at the pixel scale
                               # gives 0.97-1.03 (flat fields, white noise), the shifted examples and GoPro 0.34-0.88
GREEN_DISTRIBUTION_RATIO = 3.0 # tagged pair's quantile distance / (other pair's + floor): valid files at most
                               # 0.98 (lines aside), the shifted examples and GoPro 11.5-55
GREEN_SPLIT_SHARE = 0.02       # the GoPro's two greens are distributed 0.25 % of their level apart (one site's
                               # two halves 0.15 %): greens of a real sensor may differ, 8x that is allowed
_QUANTILES = np.linspace(0.02, 0.98, 49)
_QUANTILE_SAMPLES = 1 << 17    # values per site the quantiles are taken from (an evenly spaced grid)


@dataclasses.dataclass(frozen=True)
class LayoutProblem:
    """One finding about the raw IFD's pixel data: `refusal` (the tags contradict the data) or
    `warning` (the data is missing or short); both one short line."""

    refusal: Optional[str] = None
    warning: Optional[str] = None


@dataclasses.dataclass(frozen=True)
class _Layout:
    """The raw IFD's segment geometry, read from the tags as stored (tifffile repairs some)."""

    kind: str            # 'strips' or 'tiles'
    photometric: int
    width: int
    height: int
    samples: int         # samples per pixel in one segment (1 when planar-separate)
    planes: int
    bits: int
    compression: int
    segment_rows: int    # RowsPerStrip or TileLength
    segment_width: int   # ImageWidth or TileWidth
    offsets: tuple
    counts: tuple

    def expected_segments(self) -> int:
        down = math.ceil(self.height / self.segment_rows)
        across = math.ceil(self.width / self.segment_width) if self.kind == "tiles" else 1
        return down * across * self.planes

    def row_bytes(self) -> int:
        return math.ceil(self.segment_width * self.samples * self.bits / 8)


def _values(page, code) -> tuple:
    value = page.tags.valueof(code)
    if value is None:
        return ()
    return tuple(int(v) for v in np.atleast_1d(np.asarray(value)).ravel())


def _layout(page) -> _Layout:
    width, height = int(page.imagewidth), int(page.imagelength)
    samples = int(page.samplesperpixel or 1)
    bits_tag = _values(page, 258)
    bits = max(bits_tag) if bits_tag else 1   # TIFF 6.0 default: 1
    separate = int(getattr(page, "planarconfig", 1) or 1) == 2
    kind = "tiles" if page.tags.get(322) is not None else "strips"
    if kind == "tiles":
        rows, across = int(page.tags.valueof(323) or 0), int(page.tags.valueof(322) or 0)
    else:
        rows_tag = _values(page, 278)
        rows = min(rows_tag[0], height) if rows_tag and rows_tag[0] > 0 else height
        across = width
    offsets_code, counts_code = _OFFSET_TAGS[kind]
    return _Layout(kind, int(page.photometric or 0), width, height, 1 if separate else samples, samples if separate else 1, bits,
                   int(page.compression), max(rows, 0), max(across, 0),
                   _values(page, offsets_code), _values(page, counts_code))


def _pointed_ifd_ranges(handle, byteorder: str, offset: int, file_size: int) -> list:
    """(start, end, what) of an IFD that a pointer tag names (EXIF 34665, GPS 34853; TIFF 6.0
    section 2: a 2-byte entry count, 12-byte entries, a 4-byte next offset) and of its entries'
    values stored outside them; [] when it cannot be read."""
    if not 0 < offset < file_size - 2:
        return []
    handle.seek(offset)
    count = int(np.frombuffer(handle.read(2), np.dtype(np.uint16).newbyteorder(byteorder))[0])
    entries = handle.read(_IFD_ENTRY_BYTES * count)
    ranges = [(offset, offset + 2 + _IFD_ENTRY_BYTES * count + 4, f"the IFD at byte {offset}")]
    entry = np.dtype([("code", "u2"), ("type", "u2"), ("count", "u4"), ("value", "u4")]).newbyteorder(byteorder)
    for code, kind, number, value in np.frombuffer(entries[: len(entries) // 12 * 12], entry).tolist():
        size = _TYPE_BYTES.get(kind, 1) * number
        if size > 4:
            ranges.append((value, value + size, f"the value of tag {code}"))
    return ranges


def _structure_ranges(pages, handle=None, byteorder: str = "<", file_size: int = 0) -> list:
    """(start, end, what) of the TIFF header, each IFD's entries and each tag value stored
    outside its entry (the EXIF and GPS IFDs' too, when `handle` is given): bytes that pixel data
    must not share."""
    ranges = [(0, _HEADER_BYTES, "the TIFF header")]
    for page in pages:
        start = int(page.offset)
        ranges.append((start, start + 2 + _IFD_ENTRY_BYTES * len(page.tags) + 4, f"the IFD at byte {start}"))
        for tag in page.tags.values():
            size = int(tag.valuebytecount)
            if size > 4 and int(tag.valueoffset) != int(tag.offset) + 8:   # stored outside the entry
                ranges.append((int(tag.valueoffset), int(tag.valueoffset) + size, f"the value of tag {tag.code}"))
            if tag.code in _POINTER_TAGS and handle is not None:
                pointer = np.frombuffer(_entry_value_bytes(handle, tag), np.dtype(np.uint32).newbyteorder(byteorder))
                if pointer.size:
                    ranges += _pointed_ifd_ranges(handle, byteorder, int(pointer[0]), file_size)
    return ranges


def _entry_value_bytes(handle, tag) -> bytes:
    """The 4 bytes of a pointer tag's value field, as stored (8 bytes into its entry)."""
    handle.seek(int(tag.offset) + 8)
    return handle.read(4)


def _geometry_refusal(layout: _Layout) -> Optional[str]:
    if layout.photometric == _PHOTOMETRIC_CFA and layout.samples * layout.planes != 1:
        return (f"SamplesPerPixel {layout.samples * layout.planes}, but a CFA image has one sample per pixel "
                "(DNG spec ch. 4 'SamplesPerPixel')")
    if layout.samples < 1:
        return f"SamplesPerPixel {layout.samples} is not a number of samples"
    if not 1 <= layout.bits <= 32:
        return f"BitsPerSample {layout.bits} is outside 1..32"
    if layout.width < 1 or layout.height < 1:
        return f"ImageWidth x ImageLength {layout.width}x{layout.height} is empty"
    if layout.segment_rows < 1 or layout.segment_width < 1:
        name = "TileWidth/TileLength" if layout.kind == "tiles" else "RowsPerStrip"
        return f"{name} gives empty {layout.kind}"
    if len(layout.counts) != len(layout.offsets):
        return (f"{len(layout.offsets)} {layout.kind} but {len(layout.counts)} byte counts: "
                "the pixel data's tags disagree")
    return None


def _overlap_refusal(layout: _Layout, pages, handle, byteorder: str, file_size: int) -> Optional[str]:
    """Pixel data must lie beside the file's structure, and segments beside each other (two
    segments at the same place, a writer's shared tile, are allowed)."""
    segments = sorted(set(zip(layout.offsets, layout.counts)))
    structure = _structure_ranges(pages, handle, byteorder, file_size)
    for offset, count in segments:
        for start, end, what in structure:
            if count > 0 and offset < end and start < offset + count:
                return (f"pixel data at bytes {offset}..{offset + count} lies on {what}: "
                        f"{'StripOffsets' if layout.kind == 'strips' else 'TileOffsets'} is wrong")
    for (offset, count), (next_offset, _) in zip(segments, segments[1:]):
        if offset + count > next_offset:
            return f"{layout.kind} at bytes {offset} and {next_offset} overlap: the pixel data's tags are wrong"
    return None


def _uncompressed_refusal(layout: _Layout) -> Optional[str]:
    """Each uncompressed segment holds exactly its rows (a last strip may be written full size,
    a count may be rounded up to an even number of bytes)."""
    full = layout.row_bytes() * layout.segment_rows
    last_rows = layout.height - (math.ceil(layout.height / layout.segment_rows) - 1) * layout.segment_rows
    per_plane = len(layout.counts) // max(layout.planes, 1)
    for index, count in enumerate(layout.counts):
        allowed = {full}
        if layout.kind == "strips" and (index + 1) % max(per_plane, 1) == 0:
            allowed.add(layout.row_bytes() * last_rows)
        allowed |= {size + size % 2 for size in allowed}
        if count not in allowed:
            expected = " or ".join(str(size) for size in sorted(allowed))
            return (f"uncompressed {layout.kind[:-1]} {index} has {count} bytes; "
                    f"{layout.segment_width} x {min(layout.segment_rows, layout.height)} samples of "
                    f"{layout.bits} bits need {expected}: size tags disagree with the data")
    return None


def _lossless_jpeg_frame(handle, offset: int, count: int) -> Optional[tuple]:
    """(precision, rows, columns, components) from the first SOF3 frame header of a lossless
    JPEG stream (ITU T.81 B.2.2), or None when the stream has none in its first 4 KiB."""
    handle.seek(offset)
    data = handle.read(min(count, 4096))
    at = data.find(b"\xff\xc3")
    if at < 0 or at + 10 > len(data):
        return None
    precision, rows, columns, components = data[at + 4], int.from_bytes(data[at + 5:at + 7], "big"), \
        int.from_bytes(data[at + 7:at + 9], "big"), data[at + 9]
    return precision, rows, columns, components


def _lossless_jpeg_refusal(layout: _Layout, handle) -> Optional[str]:
    """Every segment must start with a JPEG SOI marker (ITU T.81 B.2.1), and the first segment's
    frame must fit its BitsPerSample and hold the segment's samples."""
    if not layout.offsets or layout.counts[0] <= 0:
        return None
    for index, offset in enumerate(layout.offsets):
        handle.seek(offset)
        if handle.read(2) != b"\xff\xd8":
            return (f"{layout.kind[:-1]} {index} at byte {offset} does not start a JPEG stream (no SOI "
                    "marker): Compression 7 or the offsets are wrong")
    frame = _lossless_jpeg_frame(handle, layout.offsets[0], layout.counts[0])
    if frame is None:
        return (f"{layout.kind[:-1]} 0 at byte {layout.offsets[0]} holds no lossless JPEG frame "
                "(SOF3): Compression 7 or the offsets are wrong")
    precision, rows, columns, components = frame
    if precision > layout.bits:
        return f"lossless JPEG data of {precision} bits, but BitsPerSample is {layout.bits}"
    if rows * columns * components != layout.segment_rows * layout.segment_width * layout.samples:
        return (f"lossless JPEG {layout.kind[:-1]} 0 holds {rows}x{columns}x{components} samples, its "
                f"tags say {layout.segment_rows}x{layout.segment_width}x{layout.samples}")
    return None


def _missing_warning(layout: _Layout, file_size: int) -> Optional[str]:
    """Pixel data absent or cut short while the tags agree with each other."""
    expected = layout.expected_segments()
    if len(layout.offsets) != expected:
        return (f"raw image has {len(layout.offsets)} {layout.kind} with {len(layout.counts)} byte counts, "
                f"expected {expected}: pixel data incomplete")
    ends = [offset + count for offset, count in zip(layout.offsets, layout.counts)]
    if ends and max(ends) > file_size:
        return f"raw image data runs to byte {max(ends)} but the file has {file_size} bytes: file truncated"
    if layout.kind == "tiles" and layout.segment_width > layout.width:
        return (f"TileWidth {layout.segment_width} is wider than ImageWidth {layout.width}: LibRaw would "
                "wrap each tile's rows at the image width and scramble the pixels")
    total, samples = sum(layout.counts), layout.width * layout.height * layout.samples * layout.planes
    if layout.compression == _LOSSLESS_JPEG and total < samples // 8:
        return (f"compressed raw data has {total} bytes, too few for {layout.width}x{layout.height} samples "
                "(lossless JPEG needs at least 1 bit each): pixel data missing")
    return None


def _data_present(layout: _Layout, file_size: int) -> bool:
    """Whether the segments hold pixel data (at least one bit per sample, or `_TOKEN_BYTES`; for
    uncompressed data, also when the file holds the whole image after the first offset, whatever
    the byte counts say), as against a header-only file whose pixel data was left out."""
    samples = layout.width * layout.height * layout.samples * layout.planes
    if sum(layout.counts) >= min(samples // 8, _TOKEN_BYTES):
        return True
    whole = layout.row_bytes() * layout.height * layout.planes
    return layout.compression == _UNCOMPRESSED and bool(layout.offsets) and \
        file_size - min(layout.offsets) >= whole


def _segment_count_refusal(layout: _Layout, file_size: int) -> Optional[str]:
    """With the pixel data present, the number of segments must be the one the size tags give."""
    expected = layout.expected_segments()
    if len(layout.offsets) == expected or not _data_present(layout, file_size):
        return None
    return (f"{len(layout.offsets)} {layout.kind} of pixel data, but ImageWidth x ImageLength "
            f"{layout.width}x{layout.height} in {layout.kind} of {layout.segment_width}x{layout.segment_rows} "
            f"need {expected}: size tags disagree with the data")


def layout_problem(page, pages, handle, file_size: int, byteorder: str = "<") -> LayoutProblem:
    """Check the raw IFD `page` (a tifffile TiffPage) against the file: `pages` are the IFDs read
    (their entries and values must not be overwritten by pixel data), `handle` a binary file
    object of the DNG (to read a lossless JPEG frame header). Returns what was found."""
    layout = _layout(page)
    refusal = _geometry_refusal(layout) or _overlap_refusal(layout, pages, handle, byteorder, file_size)
    if refusal is None and layout.compression in (_UNCOMPRESSED, _LOSSLESS_JPEG):
        refusal = _segment_count_refusal(layout, file_size)
    if refusal is None and layout.compression == _UNCOMPRESSED and _data_present(layout, file_size):
        refusal = _uncompressed_refusal(layout)
    warning = None if refusal else _missing_warning(layout, file_size)
    if refusal is None and warning is None and layout.compression == _LOSSLESS_JPEG:
        refusal = _lossless_jpeg_refusal(layout, handle)
    return LayoutProblem(refusal, warning)


def stored_values_problem(page, handle, byteorder: str, white_level: float, chunks: int = 16,
                          chunk_bytes: int = 8192) -> Optional[str]:
    """Uncompressed 8- or 16-bit data, sampled without decoding (`chunks` reads of `chunk_bytes`
    spread over the data): more than `MAX_SHARE_ABOVE_WHITE` of the values over `FAR_ABOVE_WHITE` x
    WhiteLevel means the WhiteLevel (or BitsPerSample) tag is wrong. Lets commands that read tags only (profile
    fitting) refuse such a file too. None when the data is not of that kind or is missing."""
    layout = _layout(page)
    if layout.compression != _UNCOMPRESSED or layout.bits not in (8, 16) or not layout.counts:
        return None
    dtype = np.dtype(np.uint8 if layout.bits == 8 else np.uint16).newbyteorder(byteorder)
    total = sum(layout.counts)
    values = []
    for k in range(chunks):
        position = int(total * (k + 0.5) / chunks)
        for offset, count in zip(layout.offsets, layout.counts):
            if position < count:
                start = offset + position // dtype.itemsize * dtype.itemsize
                handle.seek(start)
                size = min(chunk_bytes, offset + count - start) // dtype.itemsize * dtype.itemsize
                values.append(np.frombuffer(handle.read(size), dtype=dtype)[: size // dtype.itemsize])
                break
            position -= count
    sample = np.concatenate(values) if values else np.zeros(0)
    if sample.size == 0:
        return None
    above = float(np.count_nonzero(sample > FAR_ABOVE_WHITE * white_level)) / sample.size
    if above <= MAX_SHARE_ABOVE_WHITE:
        return None
    return (f"{100 * above:.0f} % of the stored values (sampled, largest {int(sample.max())}) exceed WhiteLevel "
            f"{white_level:g} by half or more: WhiteLevel or BitsPerSample disagrees with the data")


def bits_problem(bits: int, white_level: float, has_linearization_table: bool) -> Optional[str]:
    """A WhiteLevel that BitsPerSample cannot store (DNG spec ch. 4 'WhiteLevel'); with a
    LinearizationTable the levels are in linearised values and any size is allowed."""
    if has_linearization_table or white_level <= 2 ** bits - 1:
        return None
    return (f"BitsPerSample {bits} stores values up to {2 ** bits - 1}, but WhiteLevel is {white_level:g}: "
            "the tags disagree with each other")


@dataclasses.dataclass(frozen=True)
class _PhaseEvidence:
    """What a 2x2 Bayer raster's two diagonals say about which one holds the greens (one pair
    each: the tagged greens, the other diagonal's red and blue)."""

    tagged_steps: float     # tagged pair's pixel gap / its sites' own diagonal step
    other_steps: float      # the same for the other pair (inf when that pair does not vary)
    tagged_distance: float  # mean distance of the tagged pair's quantiles (DN)
    other_distance: float
    floor: float            # quantile distance of one site's two halves (alternate rows of tiles), + 1 DN
    tagged_level: float     # mean of the tagged pair's values above black (DN)

    def pixel_test(self) -> bool:
        return self.tagged_steps > GREEN_PHASE_RATIO and self.other_steps < GREEN_SHARED_RATIO

    def distribution_test(self) -> bool:
        return (self.tagged_distance > GREEN_DISTRIBUTION_RATIO * (self.other_distance + self.floor)
                and self.tagged_distance > GREEN_SPLIT_SHARE * max(self.tagged_level, 0.0))


def _site_planes(mosaic: np.ndarray, black_level) -> list:
    """The four sites of the 2x2 tile as float planes above their black level, row-major."""
    black = np.asarray(black_level, np.float64).ravel()
    black = black if black.size == 4 else np.full(4, float(black.min()) if black.size else 0.0)
    height, width = mosaic.shape[0] // 2 * 2, mosaic.shape[1] // 2 * 2
    return [mosaic[i:height:2, j:width:2].astype(np.float64) - black[2 * i + j] for i in (0, 1) for j in (0, 1)]


def _diagonal_step(plane: np.ndarray) -> float:
    """Mean absolute difference of one site between diagonally neighbouring tiles (2 px each way)."""
    falling = np.mean(np.abs(plane[1:, 1:] - plane[:-1, :-1]))
    rising = np.mean(np.abs(plane[1:, :-1] - plane[:-1, 1:]))
    return float(falling + rising) / 2


def _quantile_distance(first: np.ndarray, second: np.ndarray) -> float:
    """Mean absolute difference of two planes' 2nd..98th percentiles: the 1-Wasserstein distance of
    their distributions, which on the line is the mean gap between the quantile functions (Villani,
    *Topics in Optimal Transportation*, 2003, ch. 2), tails trimmed. Planes of more than
    `_QUANTILE_SAMPLES` values give an evenly spaced grid of them (the same places in both)."""
    step = max(1, math.ceil(math.sqrt(max(first.size, second.size) / _QUANTILE_SAMPLES)))
    return float(np.mean(np.abs(np.quantile(first[::step, ::step], _QUANTILES)
                                - np.quantile(second[::step, ::step], _QUANTILES))))


def _phase_evidence(sites: list, green: list, other: list) -> _PhaseEvidence:
    """The two tests' figures for the site planes `sites`, `green` and `other` the indices of the
    tagged greens and of the other diagonal (see `_green_phase_finding`)."""
    def steps(pair):
        gap = float(np.mean(np.abs(sites[pair[0]] - sites[pair[1]])))
        step = (_diagonal_step(sites[pair[0]]) + _diagonal_step(sites[pair[1]])) / 2
        return gap, step
    tagged_gap, tagged_step = steps(green)
    other_gap, other_step = steps(other)
    floor = 1.0 + float(np.mean([_quantile_distance(plane[0::2], plane[1::2]) for plane in sites]))
    return _PhaseEvidence(
        tagged_steps=tagged_gap / max(tagged_step, 1.0),
        other_steps=other_gap / other_step if other_step > 1.0 else math.inf,
        tagged_distance=_quantile_distance(sites[green[0]], sites[green[1]]),
        other_distance=_quantile_distance(sites[other[0]], sites[other[1]]),
        floor=floor, tagged_level=float(np.mean([sites[k].mean() for k in green])))


def _green_phase_finding(mosaic: np.ndarray, black_level, cfa_pattern) -> LayoutProblem:
    """Are the greens where `cfa_pattern` says? Data read one pixel or one row off (offsets or
    width wrong) puts the other diagonal of the 2x2 tile, red and blue, where the tags say green.

    Two tests, each asking which diagonal holds the two samples of one filter:
    - pixel scale: the tagged pair's mean gap, over the mean step of each of its sites between
      diagonally neighbouring tiles (2 px away), is above `GREEN_PHASE_RATIO` (it differs more
      than one colour does from itself), while the other pair's is below `GREEN_SHARED_RATIO`
      (it shares the content at the pixel scale: closer than 2 px steps, which content that is
      noise at that scale never is);
    - distributions: the two greens sample one filter, so their values have one distribution
      whatever the content (smooth or not), while red and blue differ under any light that is not
      neutral in raw: the tagged pair's quantiles lie `GREEN_DISTRIBUTION_RATIO` times farther
      apart than the other pair's (plus a floor: the distance between one site's two halves, the
      spread of sampling and content), and more than `GREEN_SPLIT_SHARE` of their level apart
      (what a real sensor's two greens may differ by).
    Both tests must point to the other diagonal for a refusal. Content with detail at the pixel
    pitch (lines 1-2 px wide) can make either test point there on a sound file: 2x2-periodic
    content whose colours happen to match a shifted flat field is, in the raster, exactly that
    field shifted. One test alone gives a warning and the pixels are used; the distributions
    alone give none when both pairs differ more than one colour from itself (detail at the pixel
    pitch: the two greens do not see the same content, so their distributions need not agree).
    Neither test sees a shift of content whose red and blue read alike (a light that makes them
    equal in raw): the two diagonals then look the same, and such a shift passes without a word.
    Before issue 44 the test was the tagged greens' gap over red against blue, above 2.0: it
    refused white noise, whose two greens are as unrelated as any two pixels."""
    pattern = tuple(int(c) for c in cfa_pattern or ())
    if len(pattern) != 4 or pattern.count(1) != 2 or min(mosaic.shape) < 8:
        return LayoutProblem()
    green = [k for k in range(4) if pattern[k] == 1]
    other = [k for k in range(4) if pattern[k] != 1]
    if green not in ([0, 3], [1, 2]):   # greens side by side: not a Bayer tile, nothing to test
        return LayoutProblem()
    found = _phase_evidence(_site_planes(mosaic, black_level), green, other)
    pixel, distribution = found.pixel_test(), found.distribution_test()
    if pixel and distribution:
        return LayoutProblem(refusal=(
            f"the pixel data is shifted against its CFAPattern (offsets or width wrong): the tagged green sites "
            f"differ {found.tagged_steps:.1f} times as much as one colour from itself 2 px away, red and blue match "
            f"({found.other_steps:.2f}), and their values are distributed {found.tagged_distance:.0f} DN apart "
            f"against {found.other_distance:.0f} DN"))
    detail = found.tagged_steps > GREEN_PHASE_RATIO and found.other_steps > GREEN_PHASE_RATIO
    if pixel or (distribution and not detail):
        which = "pixel differences" if pixel else "value distributions"
        return LayoutProblem(warning=(
            f"the pixel data may be shifted against its CFAPattern: the {which} of the green sites fit the "
            "other diagonal better, the other test does not confirm it (content with detail at the pixel "
            "pitch, e.g. lines 1-2 px wide, looks the same); pixels used as tagged"))
    return LayoutProblem()


def decoded_problem(mosaic: np.ndarray, black_level, white_level: float, cfa_pattern=None) -> Optional[str]:
    """The refusal of `decoded_finding`, or None (its warnings dropped)."""
    return decoded_finding(mosaic, black_level, white_level, cfa_pattern).refusal


def decoded_finding(mosaic: np.ndarray, black_level, white_level: float, cfa_pattern=None) -> LayoutProblem:
    """A decoded raster its tags cannot describe: values over `FAR_ABOVE_WHITE` x WhiteLevel in more
    than `MAX_SHARE_ABOVE_WHITE` of the pixels (bytes read at the wrong place or width), a constant
    raster outside black..white, zeros in most pixels of a camera whose black level is at least
    `ZERO_FILL_MIN_BLACK` (LibRaw's fill for data it could not find) or in its first two pixels
    (offsets moved back into the zero padding before the data: the image shifted by whole CFA
    tiles, which the phase check cannot see), or the CFA's green sites out of phase with
    `cfa_pattern` (`_green_phase_finding`: refused when two tests agree, a warning when one
    points there). Returns a `LayoutProblem` with a refusal, a warning or neither."""
    if mosaic.size == 0:
        return LayoutProblem(refusal="decoded raster is empty")
    black = float(np.min(np.asarray(black_level, np.float64)))
    largest, smallest = int(mosaic.max()), int(mosaic.min())
    if largest == smallest and not black <= largest <= white_level:
        return LayoutProblem(refusal=f"every decoded pixel is {largest}, outside the tagged range "
                                     f"{black:g}..{white_level:g}: the pixel data is not where the tags say")
    above = float(np.count_nonzero(mosaic > FAR_ABOVE_WHITE * white_level)) / mosaic.size
    if above > MAX_SHARE_ABOVE_WHITE:
        return LayoutProblem(refusal=f"{100 * above:.1f} % of the decoded pixels exceed WhiteLevel {white_level:g} "
                                     f"by half or more (largest {largest}): the pixel data does not match its tags")
    if black >= ZERO_FILL_MIN_BLACK and mosaic.shape[1] >= 2 and not mosaic[0, :2].any():
        return LayoutProblem(refusal=f"the raster starts with zeros, far below the black level {black:g}: the strip or "
                                     "tile offsets point before the pixel data")
    if black >= ZERO_FILL_MIN_BLACK:
        zeros = float(np.count_nonzero(mosaic == 0)) / mosaic.size
        if zeros > ZERO_FILL_SHARE:
            return LayoutProblem(refusal=f"{100 * zeros:.0f} % of the decoded pixels are 0, far below the black level "
                                         f"{black:g}: pixel data missing")
    return _green_phase_finding(mosaic, black_level, cfa_pattern)
