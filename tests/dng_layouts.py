"""Small DNGs with the tag layouts of real cameras, written with tifffile for the tests.

`write_layout` starts from g2r_jax's own tags for a `DngInfo` and then drops, adds or replaces
tags, or changes the raw IFD's Compression code in place (the pixel data stays uncompressed: the
reader must decide from the tag alone).
"""

from __future__ import annotations

import io
import struct

import numpy as np
import tifffile

from g2r_jax.io import dng_write


def write_layout(path, mosaic, info, *, add=(), drop=(), compression=None):
    """Write `mosaic` and `info` as a DNG at `path`, with tags `add` ((code, type, count, value))
    added (replacing tags of the same code), tag codes `drop` left out, and `compression` set."""
    add = [tuple(t) + (True,) if len(t) == 4 else tuple(t) for t in add]
    replaced = set(drop) | {t[0] for t in add}
    tags = [t for t in dng_write._extratags(path, mosaic, info) if t[0] not in replaced] + add
    tags.sort(key=lambda t: t[0])
    buffer = io.BytesIO()
    with tifffile.TiffWriter(buffer, byteorder="<", bigtiff=False) as tif:
        tif.write(np.ascontiguousarray(mosaic, dtype=np.uint16), photometric=32803, compression=None,
                  rowsperstrip=mosaic.shape[0], software=False, description=None, metadata=None,
                  datetime=None, resolution=None, extratags=tags)
    data = bytearray(buffer.getvalue())
    if compression is not None:
        with tifffile.TiffFile(io.BytesIO(bytes(data))) as tif:
            offset = tif.pages.first.tags[259].valueoffset
        data[offset:offset + 2] = struct.pack("<H", compression)
    with open(path, "wb") as handle:
        handle.write(bytes(data))
    return path
