"""Mutations of the tags that say where a DNG's pixels are and how they are packed (issue 34).

A fuzzer found that LibRaw decodes a DNG whose BitsPerSample, ImageWidth or StripOffsets lie about
the data into garbage without a word. These mutators rewrite one such tag of the raw IFD in place
(the file keeps its size; nothing else changes) so that a test or `benchmarks/fuzz_reader.py` can
ask of the reader: is every file whose decoded pixels would differ from the truth refused, by name?

Classes (`CLASSES`): one entry per layout tag, each with values chosen relative to the seed's own
(one column short, two bytes further, ...) and absolute ones (0, 1, 2 ** 32 - 1); `random_mutation`
draws a class, a value, and sometimes a second tag. A mutation writes the value into the tag's
existing slot (SHORT or LONG, count 1 or the first of several), as a corrupting writer would.

`truth(path)`: the seed's decoded mosaic; `outcome(path, truth)`: what the reader did with a
mutated copy: 'refused' (DngError naming the file, from `read_dng_info`), 'pixels refused' (tags
read, `read_dng_pixels` refused by name), 'same pixels' (accepted, decoded exactly as the seed:
the mutation was harmless), 'other size, same pixels' (a tiled file whose ImageWidth/ImageLength
moved within its last tile: LibRaw crops the tiles or keeps their padding, every pixel shared with
the seed is the seed's; TIFF 6.0 section 15 lets tiles reach past the image, so no tag says
otherwise), 'silently corrupt' (accepted with other pixels: the failure issue 34 is about), or
'unnamed error' / 'traceback' (an error without the file's name, or not a DngError).
"""

from __future__ import annotations

import io
import random
import struct
from pathlib import Path

import numpy as np

OUTCOMES = ("refused", "pixels refused", "same pixels", "other size, same pixels", "silently corrupt",
            "unnamed error", "traceback")
_FORMATS = {3: "H", 4: "I", 16: "Q"}   # SHORT, LONG, LONG8


def raw_entries(data: bytes) -> dict:
    """{tag code: (entry offset, type, count, value offset)} of the raw IFD, and 'file_size'."""
    import tifffile

    from g2r_jax.io.dng_read import _find_raw_ifd

    with tifffile.TiffFile(io.BytesIO(data)) as tif:
        raw = _find_raw_ifd(tif)
        entries = {code: (tag.offset, int(tag.dtype), tag.count, tag.valueoffset)
                   for code, tag in raw.tags.items()}
        entries["byteorder"] = tif.byteorder
    return entries


def current(data: bytes, entries: dict, code: int) -> int:
    """The first value of tag `code` as stored."""
    _, dtype, _, at = entries[code]
    form = entries["byteorder"] + _FORMATS[dtype]
    return struct.unpack_from(form, data, at)[0]


def with_value(data: bytes, entries: dict, code: int, value: int) -> bytes:
    """`data` with the first value of tag `code` replaced (clipped to the slot's type)."""
    _, dtype, _, at = entries[code]
    fmt = _FORMATS[dtype]
    value = int(value) % (1 << (8 * struct.calcsize(fmt)))
    out = bytearray(data)
    struct.pack_into(entries["byteorder"] + fmt, out, at, value)
    return bytes(out)


def _bits(old, size):
    return [8, 12, 0, 1, 10, 14, 7, 15, 17, 24, 32, 33, old - 1, old + 1]


def _width(old, size):
    return [old - 1, old + 1, old - 2, old + 2, old // 2, 2 * old, 0, 1, old - 16, old + 16]


def _offset(old, size):
    return [0, 1, 8, 16, old - 1, old + 1, old - 2, old + 2, old - 4, old - 8, old - 12, old + 4096, size, size - 2,
            2 ** 32 - 1]


def _count(old, size):
    return [old - 1, old + 1, old - 2, old + 2, old // 2, 2 * old, 0, 1, 2 ** 32 - 1, old - 4096]


def _rows(old, size):
    return [1, 2, 0, old - 1, old + 1, old // 2, 2 ** 16 - 1, 2 ** 32 - 1]


def _white(old, size):
    return [255, 1023, old // 8, old // 64, 0, 1, 2 ** 16 - 1]


def _compression(old, size):
    return [7, 0, 2, 5, 8, 34892, 65535]


def _samples(old, size):
    return [3, 2, 0, 4]


# class name -> (tag codes it may hit, the value generator)
CLASSES = {
    "BitsPerSample": ((258,), _bits),
    "ImageWidth": ((256,), _width),
    "ImageLength": ((257,), _width),
    "StripOffsets": ((273, 324), _offset),
    "StripByteCounts": ((279, 325), _count),
    "RowsPerStrip": ((278, 322, 323), _rows),
    "WhiteLevel": ((50717,), _white),
    "Compression": ((259,), _compression),
    "SamplesPerPixel": ((277,), _samples),
}


def mutations(data: bytes, entries: dict | None = None):
    """Every listed mutation of `data`: (class, description, mutated bytes)."""
    entries = entries or raw_entries(data)
    for name, (codes, values) in CLASSES.items():
        for code in codes:
            if code not in entries or entries[code][1] not in _FORMATS:
                continue
            old = current(data, entries, code)
            for value in dict.fromkeys(values(old, len(data))):
                if value != old:
                    yield name, f"tag {code}: {old} -> {value}", with_value(data, entries, code, value)


def random_mutation(data: bytes, entries: dict, rng: random.Random) -> tuple:
    """One drawn mutation: a class, one of its values (or a small random shift, or a random
    32-bit value), and with probability 0.2 a second class on top."""
    labels, out = [], data
    for _ in range(2 if rng.random() < 0.2 else 1):
        name = rng.choice([n for n, (codes, _) in CLASSES.items() if any(c in entries for c in codes)])
        codes, values = CLASSES[name]
        code = rng.choice([c for c in codes if c in entries])
        old = current(out, entries, code)
        draw = rng.random()
        value = (rng.choice(values(old, len(data))) if draw < 0.6 else
                 old + rng.randint(-64, 64) if draw < 0.85 else rng.getrandbits(32))
        out = with_value(out, entries, code, value)
        labels.append((name, f"tag {code}: {old} -> {int(value) % 2 ** 32}"))
    return "+".join(n for n, _ in labels), ", ".join(d for _, d in labels), out


def truth(path: Path) -> np.ndarray:
    from g2r_jax.io.dng_read import read_dng_pixels

    return read_dng_pixels(path)


def outcome(path: Path, true_mosaic: np.ndarray) -> tuple:
    """(one of OUTCOMES, the message or '') for the mutated DNG at `path`."""
    from g2r_jax.io.dng_info import DngError
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels

    try:
        info = read_dng_info(path)
    except DngError as error:
        return ("refused" if path.name in str(error) else "unnamed error"), str(error)
    except Exception as error:  # noqa: BLE001 - anything else escaping the reader is a finding
        return "traceback", f"{type(error).__name__}: {error}"
    try:
        mosaic = read_dng_pixels(path, info)
    except DngError as error:
        return ("pixels refused" if path.name in str(error) else "unnamed error"), str(error)
    except Exception as error:  # noqa: BLE001
        return "traceback", f"{type(error).__name__}: {error}"
    if mosaic.shape == true_mosaic.shape and np.array_equal(mosaic, true_mosaic):
        return "same pixels", ""
    rows, columns = min(mosaic.shape[0], true_mosaic.shape[0]), min(mosaic.shape[1], true_mosaic.shape[1])
    if np.array_equal(mosaic[:rows, :columns], true_mosaic[:rows, :columns]):
        return "other size, same pixels", f"decoded {mosaic.shape}, the truth {true_mosaic.shape}"
    return "silently corrupt", f"decoded {mosaic.shape}, max {int(mosaic.max())}"
