"""A camera's lens-shading correction (DNG OpcodeList2), as gain planes to invert in a synthetic RAW.

Real DNGs carry lens shading as opcodes, not in the pixels: the renderer multiplies the raw
data by a GainMap (and/or FixVignetteRadial) after linearisation and black subtraction, i.e. on
the normalised values our simulation works with (Adobe, *DNG Specification* 1.6, ch. 7
'Opcode List Processing': OpcodeList2 is applied 'just after the raw image has been mapped to
linear reference values'). To mimic a camera, divide the synthetic planes by
`shading_gain_planes(...)` and write the (rescaled) list into the DNG with
`rescale_opcode_list(...)`; a renderer that applies the opcodes then recovers the scene (the
SDK clips x * gain at 1, which values divided by gains >= 1 never reach before saturation).

Interpolation follows the spec's relative-coordinate definition as Adobe's DNG SDK evaluates it:
pixel (row, col) sits at ((row + 0.5) / H, (col + 0.5) / W) of the image; map points at
MapOrigin + i * MapSpacing; bilinear between points and the edge value outside the grid. An
area with Bottom <= Top or Right <= Left covers the whole image (the SDK's reading).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from g2r_jax.io.dng_info import DngError
from g2r_jax.io.opcodes import FixVignetteRadial, GainMap, Opcode, encode_opcode_list, parse_opcode_list

__all__ = ["LENS_SHADING_LIST", "shading_gain_planes",
           "opcode_list_image_size", "rescale_opcode_list"]

LENS_SHADING_LIST = "OpcodeList2"
_AREA_IDS = (7, 8, 9, 10, 11, 12, 13)        # opcodes whose parameters start with an area spec
_RELATIVE_IDS = (1, 2, 3, 4, 14)             # relative or position-free: valid at any image size
_SHADING_IDS = (GainMap.opcode_id, FixVignetteRadial.opcode_id)


def _as_bytes(value) -> bytes:
    return bytes.fromhex(value) if isinstance(value, str) else bytes(value)


def _lists(opcode_lists) -> dict:
    """{name: bytes} from a dict or (name, bytes-or-hex) pairs (as `profile.info.opcode_lists`)."""
    items = opcode_lists.items() if isinstance(opcode_lists, Mapping) else opcode_lists
    return {str(name): _as_bytes(value) for name, value in items}


def _axis_weights(n: int, points: int, spacing: float, origin: float) -> np.ndarray:
    """(n, points) bilinear weights of the map points for the n pixel centres along one axis."""
    weights = np.zeros((n, points))
    if points == 1:                          # a single point: constant along this axis
        weights[:, 0] = 1.0
        return weights
    index = (((np.arange(n) + 0.5) / n) - origin) / spacing
    index = np.clip(index, 0.0, points - 1)
    low = np.minimum(np.floor(index).astype(int), points - 2)
    frac = index - low
    rows = np.arange(n)
    weights[rows, low] = 1.0 - frac
    weights[rows, low + 1] += frac
    return weights


def _covered(n: int, start: int, stop: int, pitch: int, phase: int) -> np.ndarray:
    """Indices i of the pixels phase + 2 i (one CFA plane along an axis of n pixels) in the span
    start, start + pitch, ... < stop."""
    pixels = phase + 2 * np.arange(n // 2)
    return np.nonzero((pixels >= start) & (pixels < stop) & ((pixels - start) % pitch == 0))[0]


def _gain_map(where, op: GainMap, planes: np.ndarray, height: int, width: int) -> None:
    if not (op.plane <= 0 < op.plane + op.planes):
        return                               # a CFA image has one plane (0); other planes do not exist
    (sv, sh), (ov, oh) = op.spacing, op.origin
    points_v, points_h, _ = op.gains.shape
    if not np.all(np.isfinite([sv, sh, ov, oh])) or (points_v > 1 and sv <= 0) or (points_h > 1 and sh <= 0):
        raise DngError(where, f"GainMap spacing {op.spacing} / origin {op.origin} not finite and positive")
    grid = op.gains[:, :, 0].astype(np.float64)  # map plane min(plane, MapPlanes - 1) = 0
    if not np.all(np.isfinite(grid)) or np.any(grid <= 0):
        raise DngError(where, "GainMap holds non-finite or non-positive gains (cannot be inverted)")
    wv = _axis_weights(height, points_v, sv, ov)
    wh = _axis_weights(width, points_h, sh, oh)
    if op.bottom <= op.top or op.right <= op.left:   # empty area: the whole image
        rows_span, cols_span = (0, height), (0, width)
    else:
        rows_span, cols_span = (op.top, op.bottom), (op.left, op.right)
    for p, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
        rows = _covered(height, *rows_span, op.row_pitch, dy)
        cols = _covered(width, *cols_span, op.col_pitch, dx)
        if rows.size and cols.size:
            block = wv[dy + 2 * rows] @ grid @ wh[dx + 2 * cols].T
            if rows.size == height // 2 and cols.size == width // 2:
                planes[p] *= block
            else:
                planes[p][np.ix_(rows, cols)] *= block


def _vignette(where, op: FixVignetteRadial, planes: np.ndarray, height: int, width: int) -> None:
    if not np.all(np.isfinite([*op.k, op.cx, op.cy])):
        raise DngError(where, "FixVignetteRadial has non-finite parameters")
    cy, cx = op.cy * height, op.cx * width  # optical centre in pixels (edges at 0 and H, W); square pixels
    max_r2 = max(cy, height - cy) ** 2 + max(cx, width - cx) ** 2
    for p, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
        r2 = (((dy + 2 * np.arange(height // 2) + 0.5 - cy) ** 2)[:, None]
              + ((dx + 2 * np.arange(width // 2) + 0.5 - cx) ** 2)[None, :]) / max_r2
        poly = np.zeros_like(r2)
        for k in reversed(op.k):             # r2 (k0 + r2 (k1 + ... + r2 k4))
            poly = (poly + k) * r2
        if np.any(poly <= -1):
            raise DngError(where, "FixVignetteRadial gain is not positive everywhere (cannot be inverted)")
        planes[p] *= 1.0 + poly


def shading_gain_planes(opcode_lists, height: int, width: int, cfa_pattern=(0, 1, 1, 2), *,
                        list_name: str = LENS_SHADING_LIST) -> np.ndarray:
    """The gain a DNG renderer applies to each raw pixel, as (4, H/2, W/2) float32 CFA planes.

    `opcode_lists`: {name: bytes} (DngInfo.opcode_lists) or (name, hex) pairs
    (profile.info.opcode_lists); only `list_name` (OpcodeList2, spec 1.6 ch. 7) is used, since
    OpcodeList1 acts before black subtraction and OpcodeList3 after demosaicing. The planes are in
    tile order (0,0), (0,1), (1,0), (1,1) like `g2r_jax.sensor.to_planes`; each GainMap picks
    its CFA positions by Top/Left and RowPitch/ColPitch, so the gains depend on geometry only
    (`cfa_pattern` is checked to be a 2x2 tile). Gains of several opcodes multiply; no list, or a
    list without shading opcodes, gives ones. Height and width must be even; coordinates are
    those of the image the list applies to (rescale it first with `rescale_opcode_list`).
    """
    height, width = int(height), int(width)
    if height < 2 or width < 2 or height % 2 or width % 2:
        raise ValueError(f"image size {height}x{width} must be even and at least 2x2")
    if len(tuple(np.asarray(cfa_pattern).ravel())) != 4:
        raise ValueError(f"cfa_pattern must describe a 2x2 tile, got {cfa_pattern!r}")
    planes = np.ones((4, height // 2, width // 2))
    data = _lists(opcode_lists).get(list_name)
    for op in parse_opcode_list(data, list_name) if data else ():
        if isinstance(op, GainMap):
            _gain_map(list_name, op, planes, height, width)
        elif isinstance(op, FixVignetteRadial):
            _vignette(list_name, op, planes, height, width)
    return planes.astype(np.float32)


def _area(op, where="opcode list"):
    """(top, left, bottom, right, row_pitch, col_pitch) of an area-spec opcode."""
    if isinstance(op, GainMap):
        return op.top, op.left, op.bottom, op.right, op.row_pitch, op.col_pitch
    if len(op.params) < 32:
        raise DngError(where, f"{op.name} has {len(op.params)} parameter bytes, too few for an area")
    values = np.frombuffer(op.params, ">u4", 8)
    return (*(int(v) for v in values[:4]), int(values[6]), int(values[7]))


def opcode_list_image_size(data, where="opcode list"):
    """(height, width) the list was written for, guessed as the largest Bottom/Right of its
    area-spec opcodes (GainMaps normally cover the whole image), or None without such opcodes."""
    areas = [_area(op, where) for op in parse_opcode_list(data, where) if op.opcode_id in _AREA_IDS]
    areas = [a for a in areas if a[2] > a[0] and a[3] > a[1]]
    return (max(a[2] for a in areas), max(a[3] for a in areas)) if areas else None


def _scale_span(start, stop, pitch, old, new):
    """Map a pixel span [start, stop) with a pitch to a new axis length: start % pitch (the CFA
    position it selects) is kept and the rest scaled; a span reaching the old edge reaches the new."""
    phase = start % pitch
    start2 = phase + pitch * int(np.floor((start - phase) * new / old / pitch + 0.5))
    stop2 = new if stop >= old else min(new, int(np.floor(stop * new / old + 0.5)))
    return start2, max(stop2, start2 + 1)


def rescale_opcode_list(data, from_size, to_size, *, shading_only: bool = False,
                        where="opcode list") -> bytes:
    """Rewrite an opcode list written for a `from_size` (height, width) image so that it is valid
    for a `to_size` image; returns the new tag value (b"" if no opcode is left).

    GainMap, MapTable and MapPolynomial: Top/Left/Bottom/Right are pixels and are scaled (an area
    reaching the old edge reaches the new one; Top/Left keep their phase modulo the pitch, so a
    GainMap still selects the same CFA position); the map itself is in relative coordinates and is
    kept byte for byte. Opcodes in relative coordinates (Warp*, FixVignetteRadial,
    FixBadPixelsConstant) are kept as they are. Opcodes tied to pixel positions or per-row data
    (FixBadPixelsList, TrimBounds, Delta/ScalePer*) raise `DngError` unless the sizes are equal.
    `shading_only=True` keeps only GainMap and FixVignetteRadial, the opcodes
    `shading_gain_planes` inverts. `from_size=None` uses `opcode_list_image_size`.
    """
    opcodes = parse_opcode_list(data, where)
    if from_size is None:
        from_size = opcode_list_image_size(data, where)
        if from_size is None:
            raise DngError(where, "cannot tell the image size the opcode list was written for; pass from_size")
    (old_h, old_w), (new_h, new_w) = (tuple(int(v) for v in from_size), tuple(int(v) for v in to_size))
    if min(old_h, old_w, new_h, new_w) < 1:
        raise ValueError(f"image sizes must be positive, got {from_size} -> {to_size}")
    out = []
    for op in opcodes:
        if shading_only and op.opcode_id not in _SHADING_IDS:
            continue
        if (old_h, old_w) == (new_h, new_w) or op.opcode_id in _RELATIVE_IDS:
            out.append(op)
            continue
        if op.opcode_id not in (7, 8, 9):
            raise DngError(where, f"{op.name} uses pixel positions or per-row data and cannot be "
                                  f"rescaled from {old_h}x{old_w} to {new_h}x{new_w}")
        top, left, bottom, right, row_pitch, col_pitch = _area(op, where)
        if bottom > top and right > left:
            top, bottom = _scale_span(top, bottom, row_pitch, old_h, new_h)
            left, right = _scale_span(left, right, col_pitch, old_w, new_w)
            if top >= new_h or left >= new_w:
                continue                     # the area fell outside the smaller image
        if isinstance(op, GainMap):
            out.append(dataclasses.replace(op, top=top, left=left, bottom=bottom, right=right))
        else:
            head = np.array([top, left, bottom, right], ">u4").tobytes()
            out.append(Opcode(op.opcode_id, op.version, op.flags, head + op.params[16:]))
    return encode_opcode_list(out) if out else b""
