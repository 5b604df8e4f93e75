"""DNG 1.6 IlluminantData1/2/3: the white of a calibration illuminant coded 255 ('other').

Layout (Adobe DNG SDK 1.6, dng_xy_coord.cpp, dng_illuminant_data::Get/Put; stored with the
file's byte order): uint16 type, then for type 0 (white xy) x and y as RATIONALs; for type 1
(spectrum) uint32 sample count, RATIONAL minimum wavelength and spacing (nm), and the samples as
RATIONALs. A spectrum becomes a white xy as the SDK derives it (CalculateSpectrumXY): the spectrum,
linear between samples and held constant beyond its ends, weighted by the CIE 1931 2 degree
colour-matching functions at 1 nm from 360 to 830 nm (colour-science), each sum divided by its
colour-matching function's own sum.
"""

from __future__ import annotations

import struct

import numpy as np

TYPE_WHITE_XY, TYPE_SPECTRUM = 0, 1


def spectrum_to_xy(min_wavelength: float, spacing: float, samples) -> np.ndarray:
    """White xy of a sampled illuminant spectrum (see the module docstring)."""
    import colour

    samples = np.asarray(samples, np.float64)
    if min_wavelength <= 0 or spacing <= 0 or samples.size < 2 or np.any(samples < 0):
        raise ValueError("spectrum needs a positive start and spacing and at least 2 non-negative samples")
    wavelengths = min_wavelength + spacing * np.arange(samples.size)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    grid = np.arange(360, 831, dtype=np.float64)
    observer = np.asarray(cmfs[grid], np.float64)                     # (471, 3)
    light = np.interp(grid, wavelengths, samples)                      # held constant beyond the ends
    XYZ = (observer * light[:, None]).sum(axis=0) / observer.sum(axis=0)
    if XYZ.min() <= 0:
        raise ValueError("spectrum gives no valid white")
    return XYZ[:2] / XYZ.sum()


def _rationals(data: bytes, offset: int, count: int, order: str) -> np.ndarray:
    values = np.asarray(struct.unpack_from(f"{order}{2 * count}I", data, offset), np.float64).reshape(-1, 2)
    if np.any(values[:, 1] == 0):
        raise ValueError("zero denominator")
    return values[:, 0] / values[:, 1]


def parse_illuminant_data(data: bytes, byteorder: str = "<") -> np.ndarray:
    """White xy (2,) of an IlluminantData tag's bytes; ValueError naming what is wrong."""
    try:
        (kind,) = struct.unpack_from(f"{byteorder}H", data, 0)
        if kind == TYPE_WHITE_XY:
            xy = _rationals(data, 2, 2, byteorder)
        elif kind == TYPE_SPECTRUM:
            (count,) = struct.unpack_from(f"{byteorder}I", data, 2)
            if len(data) < 2 + 4 + 16 + 8 * count:
                raise ValueError(f"{count} spectrum samples announced but the tag is {len(data)} bytes")
            start, spacing = _rationals(data, 6, 2, byteorder)
            xy = spectrum_to_xy(start, spacing, _rationals(data, 22, count, byteorder))
        else:
            raise ValueError(f"unknown type {kind} (0 = white xy, 1 = spectrum)")
    except struct.error:
        raise ValueError(f"too short ({len(data)} bytes)") from None
    if not (0 < xy[0] < 1 and 0 < xy[1] < 1 and xy.sum() < 1):
        raise ValueError(f"white {tuple(np.round(xy, 6))} is not a valid xy chromaticity")
    return xy


def encode_white_xy(xy, to_rationals) -> bytes:
    """IlluminantData bytes (little-endian, type 0) for white `xy`; `to_rationals` as in dng_write."""
    parts = to_rationals(np.asarray(xy, np.float64).reshape(2), signed=False)
    return struct.pack("<H4I", TYPE_WHITE_XY, *parts)
