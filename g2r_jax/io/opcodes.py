"""DNG opcode lists (OpcodeList1/2/3 tags): parse into dataclasses and encode back.

Format: Adobe, *Digital Negative (DNG) Specification* 1.6 (2020), chapter 7 'Opcode List
Processing'. A list is big-endian: uint32 opcode count, then per opcode a uint32 opcode ID, the
4-byte DNG version that introduced it, uint32 flags (bit 0: optional, bit 1: may be skipped for
previews), uint32 parameter byte count and the parameters.

Decoded: GainMap (ID 9) and FixVignetteRadial (ID 3). Every other opcode is kept opaque
(`Opcode`: ID, version, flags, parameter bytes), so `encode_opcode_list(parse_opcode_list(b))`
returns `b` byte for byte. Structural problems raise `DngError(where, problem)`.
"""

from __future__ import annotations

import dataclasses
import struct
from typing import Union

import numpy as np

from g2r_jax.io.dng_info import DngError

__all__ = ["Opcode", "GainMap", "FixVignetteRadial", "AnyOpcode", "OPCODE_NAMES",
           "parse_opcode_list", "encode_opcode_list", "encode_opcode"]

# Spec 1.6 ch. 7, one section per opcode ('Opcode List Processing' > 'Opcodes')
OPCODE_NAMES = {1: "WarpRectilinear", 2: "WarpFisheye", 3: "FixVignetteRadial",
                4: "FixBadPixelsConstant", 5: "FixBadPixelsList", 6: "TrimBounds", 7: "MapTable",
                8: "MapPolynomial", 9: "GainMap", 10: "DeltaPerRow", 11: "DeltaPerColumn",
                12: "ScalePerRow", 13: "ScalePerColumn", 14: "WarpRectilinear2"}

FLAG_OPTIONAL = 1
FLAG_PREVIEW_SKIPPABLE = 2

_HEADER = struct.Struct(">I4BII")            # ID, version (4 bytes), flags, parameter byte count
_AREA = struct.Struct(">8I")                 # Top, Left, Bottom, Right, Plane, Planes, RowPitch, ColPitch
_GAIN_MAP_GRID = struct.Struct(">2I4dI")     # MapPointsV/H, MapSpacingV/H, MapOriginV/H, MapPlanes
_VIGNETTE = struct.Struct(">7d")             # k0..k4, cx, cy


@dataclasses.dataclass(frozen=True)
class Opcode:
    """An opcode kept as bytes (any ID); `params` are the raw parameter bytes."""

    opcode_id: int
    version: tuple = (1, 3, 0, 0)
    flags: int = 0
    params: bytes = b""

    @property
    def name(self) -> str:
        return OPCODE_NAMES.get(self.opcode_id, f"Opcode{self.opcode_id}")

    def encode_params(self) -> bytes:
        return bytes(self.params)


@dataclasses.dataclass(frozen=True, eq=False)
class GainMap:
    """GainMap (spec 1.6 ch. 7, opcode ID 9): multiply an area of the image by a 2-D gain map.

    The area is rows Top, Top+RowPitch, ... < Bottom and columns Left, Left+ColPitch, ... < Right
    (pixels of the image the list applies to) of planes Plane .. Plane+Planes-1. The map is a
    grid of MapPointsV x MapPointsH points at relative positions (0..1 of the *whole* image)
    MapOrigin + i * MapSpacing; `gains` has shape (MapPointsV, MapPointsH, MapPlanes), float32.
    """

    top: int
    left: int
    bottom: int
    right: int
    gains: np.ndarray
    spacing: tuple = (1.0, 1.0)              # (MapSpacingV, MapSpacingH)
    origin: tuple = (0.0, 0.0)               # (MapOriginV, MapOriginH)
    plane: int = 0
    planes: int = 1
    row_pitch: int = 1
    col_pitch: int = 1
    version: tuple = (1, 3, 0, 0)
    flags: int = 0

    opcode_id = 9
    name = "GainMap"

    def encode_params(self) -> bytes:
        gains = np.asarray(self.gains, dtype=np.float32)
        if gains.ndim == 2:
            gains = gains[:, :, None]
        if gains.ndim != 3 or min(gains.shape) < 1:
            raise ValueError(f"GainMap gains must have shape (points_v, points_h, map_planes), got {gains.shape}")
        area = _AREA.pack(self.top, self.left, self.bottom, self.right,
                          self.plane, self.planes, self.row_pitch, self.col_pitch)
        grid = _GAIN_MAP_GRID.pack(gains.shape[0], gains.shape[1], *map(float, self.spacing),
                                   *map(float, self.origin), gains.shape[2])
        return area + grid + gains.astype(">f4").tobytes()


@dataclasses.dataclass(frozen=True)
class FixVignetteRadial:
    """FixVignetteRadial (spec 1.6 ch. 7, opcode ID 3): gain 1 + k0 r^2 + k1 r^4 + ... + k4 r^10.

    (cx, cy) is the optical centre in relative coordinates (0..1 of width, height); r is the
    distance from it, normalised so that r = 1 at the farthest image corner.
    """

    k: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)
    cx: float = 0.5
    cy: float = 0.5
    version: tuple = (1, 3, 0, 0)
    flags: int = 0

    opcode_id = 3
    name = "FixVignetteRadial"

    def encode_params(self) -> bytes:
        if len(self.k) != 5:
            raise ValueError(f"FixVignetteRadial needs 5 coefficients k0..k4, got {len(self.k)}")
        return _VIGNETTE.pack(*map(float, self.k), float(self.cx), float(self.cy))


AnyOpcode = Union[Opcode, GainMap, FixVignetteRadial]


def _decode(where, index, opcode_id, version, flags, params: bytes) -> AnyOpcode:
    label = f"opcode {index} ({OPCODE_NAMES.get(opcode_id, f'ID {opcode_id}')})"
    if opcode_id == FixVignetteRadial.opcode_id:
        if len(params) != _VIGNETTE.size:
            raise DngError(where, f"{label}: {len(params)} parameter bytes, expected {_VIGNETTE.size}")
        *k, cx, cy = _VIGNETTE.unpack(params)
        return FixVignetteRadial(tuple(k), cx, cy, version, flags)
    if opcode_id == GainMap.opcode_id:
        head = _AREA.size + _GAIN_MAP_GRID.size
        if len(params) < head:
            raise DngError(where, f"{label}: {len(params)} parameter bytes, fewer than the {head}-byte header")
        top, left, bottom, right, plane, planes, row_pitch, col_pitch = _AREA.unpack_from(params)
        points_v, points_h, sv, sh, ov, oh, map_planes = _GAIN_MAP_GRID.unpack_from(params, _AREA.size)
        if min(points_v, points_h, map_planes) < 1 or min(planes, row_pitch, col_pitch) < 1:
            raise DngError(where, f"{label}: zero MapPoints/MapPlanes/Planes/pitch "
                                  f"({points_v}x{points_h}x{map_planes}, planes {planes}, "
                                  f"pitch {row_pitch}x{col_pitch})")
        n = points_v * points_h * map_planes
        if len(params) != head + 4 * n:
            raise DngError(where, f"{label}: {len(params)} parameter bytes, expected {head + 4 * n} "
                                  f"for a {points_v}x{points_h}x{map_planes} map")
        gains = np.frombuffer(params, ">f4", n, head).astype(np.float32).reshape(points_v, points_h, map_planes)
        return GainMap(top, left, bottom, right, gains, (sv, sh), (ov, oh), plane, planes,
                       row_pitch, col_pitch, version, flags)
    return Opcode(opcode_id, version, flags, bytes(params))


def parse_opcode_list(data, where="opcode list") -> list:
    """The opcodes of one opcode-list tag value (bytes, or a hex string as profiles store it).

    `where` (a path or a tag name) prefixes error messages: `DngError(where, problem)` for a list
    shorter than its count, an opcode running past the end, trailing bytes, or a GainMap /
    FixVignetteRadial whose parameters do not match their own sizes.
    """
    data = bytes.fromhex(data) if isinstance(data, str) else bytes(data)
    if len(data) < 4:
        raise DngError(where, f"opcode list is {len(data)} bytes, too short for its opcode count")
    (count,) = struct.unpack_from(">I", data)
    offset, opcodes = 4, []
    for index in range(count):
        if offset + _HEADER.size > len(data):
            raise DngError(where, f"opcode list truncated: it announces {count} opcodes, "
                                  f"data ends inside opcode {index} header (byte {offset} of {len(data)})")
        opcode_id, *version, flags, size = _HEADER.unpack_from(data, offset)
        offset += _HEADER.size
        if offset + size > len(data):
            raise DngError(where, f"opcode list truncated: opcode {index} "
                                  f"({OPCODE_NAMES.get(opcode_id, f'ID {opcode_id}')}) needs {size} "
                                  f"parameter bytes, {len(data) - offset} left")
        opcodes.append(_decode(where, index, opcode_id, tuple(version), flags, data[offset:offset + size]))
        offset += size
    if offset != len(data):
        raise DngError(where, f"opcode list has {len(data) - offset} bytes after its {count} opcodes")
    return opcodes


def encode_opcode(opcode: AnyOpcode) -> bytes:
    """One opcode: header (ID, version, flags, byte count) and parameters (spec 1.6 ch. 7)."""
    params = opcode.encode_params()
    version = tuple(int(v) for v in opcode.version)
    if len(version) != 4:
        raise ValueError(f"opcode version must be 4 bytes, got {opcode.version}")
    return _HEADER.pack(opcode.opcode_id, *version, int(opcode.flags), len(params)) + params


def encode_opcode_list(opcodes) -> bytes:
    """The tag value for a sequence of opcodes (the inverse of `parse_opcode_list`)."""
    opcodes = list(opcodes)
    return struct.pack(">I", len(opcodes)) + b"".join(encode_opcode(op) for op in opcodes)
