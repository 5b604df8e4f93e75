"""Writing a Bayer mosaic and its `DngInfo` as a DNG, with tifffile.

The file is one little-endian TIFF whose IFD0 *is* the raw image (NewSubFileType 0; spec ch. 2
'SubIFD Trees' recommends a preview in IFD0 but does not require one, and GoPro cameras write the
same layout), 16 bits per sample: uncompressed in one strip, or with `compression='ljpeg'` lossless
JPEG (Compression 7) in tiles of up to 256 x 256 (`g2r_jax.io.lossless_jpeg`); the pixels read back the
same either way. ISO and ExposureTime go in IFD0 as
TIFF/EP tags (no EXIF IFD); LibRaw needs at least 22x22 pixels to accept the file.
Tag types follow spec ch. 4 exactly, since LibRaw ignores colour tags stored with other types:
SRATIONAL for ColorMatrix*, CameraCalibration*, ForwardMatrix*, BaselineExposure; RATIONAL for
AnalogBalance, AsShotNeutral, AsShotWhiteXY and a fractional BlackLevel; DOUBLE for NoiseProfile.
References: Adobe, *Digital Negative (DNG) Specification* 1.6 (2020).

Output is deterministic (no timestamps, no software-version strings), so equal inputs give
byte-identical files, and `write_dng` replaces the target atomically.
"""

from __future__ import annotations

import io
from fractions import Fraction
from pathlib import Path

import numpy as np

from g2r_jax.io.atomic import atomic_write_bytes
from g2r_jax.io.dng_info import DngError, DngInfo
from g2r_jax.io.dng_read import TAGS, require_bayer_cfa, require_colour_tags
from g2r_jax.io.illuminant_data import encode_white_xy

__all__ = ["write_dng", "write_dng_bytes", "to_rationals", "COMPRESSIONS"]

# TIFF field types (TIFF 6.0 section 2)
BYTE, ASCII, SHORT, LONG, RATIONAL, UNDEFINED, SRATIONAL, DOUBLE = 1, 2, 3, 4, 5, 7, 10, 12

COMPRESSIONS = ("none", "ljpeg")   # uncompressed strip; lossless JPEG tiles (DNG Compression 7)

_SIGNED_MAX = 2**31 - 1
_UNSIGNED_MAX = 2**32 - 1


def to_rationals(values, signed: bool) -> tuple:
    """Flat (num, den, num, den, ...) ints closest to `values` (continued fractions).

    For each value the best rational approximation whose numerator and denominator fit the TIFF
    type (int32 / uint32) is chosen by `Fraction.limit_denominator`; decimals such as 0.522449
    come out exact, and any double is kept to better than 1e-9 (absolute below 1, relative above).
    """
    num_max = _SIGNED_MAX if signed else _UNSIGNED_MAX
    den_max = _SIGNED_MAX if signed else _UNSIGNED_MAX
    out = []
    for v in np.asarray(values, dtype=np.float64).ravel():
        if not np.isfinite(v):
            raise ValueError(f"cannot store {v} as a rational")
        if not signed and v < 0:
            raise ValueError(f"cannot store negative {v} as an unsigned RATIONAL")
        if abs(v) >= num_max:
            raise ValueError(f"{v} is too large for a 32-bit rational")
        limit = max(1, min(den_max, int(num_max // max(abs(v), 1.0))))
        f = Fraction(float(v)).limit_denominator(limit)
        out.extend((int(f.numerator), int(f.denominator)))
    return tuple(out)


def _ascii(text: str) -> bytes:
    return str(text).encode("ascii", "replace") + b"\x00"


def _check_geometry(where, info: DngInfo, height: int, width: int):
    """ActiveArea and DefaultCrop to write, or None when trivial; DngError when they do not fit."""
    area = info.active_area
    if area is not None:
        area = tuple(int(v) for v in area)
        if area in ((0, 0, info.height, info.width), (0, 0, height, width)):
            area = None        # the whole frame: nothing to say
        elif not (len(area) == 4 and 0 <= area[0] < area[2] <= height and 0 <= area[1] < area[3] <= width):
            raise DngError(where, f"info.active_area {area} does not fit the {width}x{height} "
                                  "mosaic; set it to None")
    active_h = height if area is None else area[2] - area[0]
    active_w = width if area is None else area[3] - area[1]
    crop = None
    if info.default_crop_origin is not None or info.default_crop_size is not None:
        origin = tuple(float(v) for v in (info.default_crop_origin or (0.0, 0.0)))
        size = tuple(float(v) for v in (info.default_crop_size or (active_w - origin[0], active_h - origin[1])))
        full_old = origin == (0.0, 0.0) and size in ((float(info.width), float(info.height)),
                                                     (float(active_w), float(active_h)))
        if not full_old:
            if (len(origin) != 2 or len(size) != 2 or min(origin) < 0 or min(size) <= 0
                    or origin[0] + size[0] > active_w or origin[1] + size[1] > active_h):
                raise DngError(where, f"default crop origin {origin} size {size} does not fit the "
                                      f"{active_w}x{active_h} active area; set them to None")
            crop = (origin, size)
    return area, crop


class _TagList:
    """The tags of one DNG as tifffile's `extratags` (code, type, count, value, writeonce);
    `add` converts a value to its TIFF type (a rational that cannot be written is a DngError)."""

    def __init__(self, where):
        self.where, self.tags = where, []

    def add(self, name, dtype, values):
        if dtype in (BYTE, UNDEFINED):
            data = bytes(values)
            self.tags.append((TAGS[name], dtype, len(data), data, True))
        elif dtype == ASCII:
            self.tags.append((TAGS[name], ASCII, 0, values, True))
        elif dtype in (RATIONAL, SRATIONAL):
            try:
                flat = to_rationals(values, signed=dtype == SRATIONAL)
            except ValueError as exc:
                raise DngError(self.where, f"{name}: {exc}") from None
            self.tags.append((TAGS[name], dtype, len(flat) // 2, flat, True))
        elif dtype == DOUBLE:
            vals = tuple(float(v) for v in np.asarray(values, dtype=np.float64).ravel())
            self.tags.append((TAGS[name], DOUBLE, len(vals), vals, True))
        else:
            vals = tuple(int(v) for v in np.asarray(values).ravel())
            self.tags.append((TAGS[name], dtype, len(vals), vals, True))


def _extratags(where, mosaic: np.ndarray, info: DngInfo) -> list:
    """The DNG tags (code, type, count, value, writeonce) for tifffile, in spec ch. 4 terms,
    sorted by code."""
    height, width = mosaic.shape
    tags = _TagList(where)
    _camera_tags(tags, info)
    _level_tags(tags, info)
    area, crop = _check_geometry(where, info, height, width)
    if crop is not None:
        tags.add("DefaultCropOrigin", RATIONAL, crop[0])
        tags.add("DefaultCropSize", RATIONAL, crop[1])
    _colour_tags(tags, info)
    if area is not None:
        tags.add("ActiveArea", LONG, area)
    _forward_opcode_noise_tags(tags, info)
    return sorted(tags.tags, key=lambda t: t[0])


def _camera_tags(tags: _TagList, info: DngInfo) -> None:
    """Version, names, CFA layout and exposure (spec ch. 4; DNG 1.6 when a third matrix or
    IlluminantData is written)."""
    uses_1_6 = len(info.color_matrices) > 2 or any(d is not None for d in tuple(info.illuminant_data or ()))
    tags.add("NewSubfileType", LONG, [0])
    tags.add("Orientation", SHORT, [1])   # 1: rows top to bottom, columns left to right (TIFF 6.0; the SDK warns without it)
    if info.make:
        tags.add("Make", ASCII, _ascii(info.make))
    if info.model:
        tags.add("Model", ASCII, _ascii(info.model))
    tags.add("CFARepeatPatternDim", SHORT, [2, 2])
    tags.add("CFAPattern", BYTE, [int(c) for c in info.cfa_pattern])
    if info.exposure_time is not None and info.exposure_time > 0:
        tags.add("ExposureTime", RATIONAL, [info.exposure_time])
    if info.iso is not None and info.iso > 0:
        tags.add("ISOSpeedRatings", SHORT, [min(65535, int(round(info.iso)))])
    tags.add("DNGVersion", BYTE, (1, 6, 0, 0) if uses_1_6 else (1, 4, 0, 0))
    tags.add("DNGBackwardVersion", BYTE, (1, 3, 0, 0) if info.opcode_lists else (1, 1, 0, 0))
    tags.add("UniqueCameraModel", ASCII, _ascii(info.unique_camera_model or
                                                " ".join(p for p in (info.make, info.model) if p) or "g2r_jax"))
    tags.add("CFAPlaneColor", BYTE, [0, 1, 2])
    tags.add("CFALayout", SHORT, [1])


def _level_tags(tags: _TagList, info: DngInfo) -> None:
    """BlackLevel (one value, or per 2x2 position) and WhiteLevel (spec ch. 4)."""
    black = np.asarray(info.black_level, dtype=np.float64).ravel()
    if black.size == 1:
        black = np.repeat(black, 4)
    if black.size != 4 or np.any(black < 0) or not np.all(np.isfinite(black)):
        raise DngError(tags.where, f"black_level must be 4 non-negative values, got {tuple(black)}")
    if np.all(black == black[0]):
        tags.add("BlackLevelRepeatDim", SHORT, [1, 1])
        black = black[:1]
    else:
        tags.add("BlackLevelRepeatDim", SHORT, [2, 2])
    if np.all(black == np.round(black)):
        tags.add("BlackLevel", LONG, black.astype(np.int64))
    else:
        tags.add("BlackLevel", RATIONAL, black)
    white = float(info.white_level)
    if not (0 < white <= 65535) or white != round(white) or white <= black.max():
        raise DngError(tags.where, f"white_level must be an integer in (black, 65535], got {white}")
    tags.add("WhiteLevel", LONG, [int(white)])


def _colour_tags(tags: _TagList, info: DngInfo) -> None:
    """ColorMatrix, CameraCalibration, AnalogBalance, the as-shot white, BaselineExposure,
    CalibrationIlluminant and IlluminantData (spec ch. 4; spec 'Colour' for their use)."""
    n_matrices = len(info.color_matrices)
    illuminants = tuple(int(i) for i in info.calibration_illuminants)
    for k, m in enumerate(info.color_matrices, start=1):
        tags.add(f"ColorMatrix{k}", SRATIONAL, np.asarray(m, dtype=np.float64).reshape(9))
    if info.camera_calibrations:
        if len(info.camera_calibrations) != n_matrices:
            raise DngError(tags.where, "camera_calibrations must match color_matrices in number")
        for k, m in enumerate(info.camera_calibrations, start=1):
            tags.add(f"CameraCalibration{k}", SRATIONAL, np.asarray(m, dtype=np.float64).reshape(9))
    if info.analog_balance is not None:
        tags.add("AnalogBalance", RATIONAL, np.asarray(info.analog_balance).reshape(3))
    if info.as_shot_neutral is not None:
        neutral = np.asarray(info.as_shot_neutral, dtype=np.float64).reshape(3)
        if np.any(neutral <= 0):
            raise DngError(tags.where, f"as_shot_neutral must be positive, got {tuple(neutral)}")
        tags.add("AsShotNeutral", RATIONAL, neutral)
    elif info.as_shot_white_xy is not None:   # spec: at most one of AsShotNeutral, AsShotWhiteXY
        tags.add("AsShotWhiteXY", RATIONAL, np.asarray(info.as_shot_white_xy).reshape(2))
    tags.add("BaselineExposure", SRATIONAL, [float(info.baseline_exposure)])
    for k, ill in enumerate(illuminants[:n_matrices], start=1):
        tags.add(f"CalibrationIlluminant{k}", SHORT, [ill])
    for k, white in enumerate(tuple(info.illuminant_data or ())[:n_matrices], start=1):
        if white is not None and illuminants[k - 1] == 255:   # DNG 1.6: the white of an 'other' illuminant
            tags.add(f"IlluminantData{k}", UNDEFINED, encode_white_xy(white, to_rationals))


def _forward_opcode_noise_tags(tags: _TagList, info: DngInfo) -> None:
    """ForwardMatrix, OpcodeList1-3 and NoiseProfile (spec ch. 4, ch. 7)."""
    if info.forward_matrices:
        if len(info.forward_matrices) != len(info.color_matrices):
            raise DngError(tags.where, "forward_matrices must match color_matrices in number")
        for k, m in enumerate(info.forward_matrices, start=1):
            tags.add(f"ForwardMatrix{k}", SRATIONAL, np.asarray(m, dtype=np.float64).reshape(9))
    for k in (1, 2, 3):
        data = info.opcode_lists.get(f"OpcodeList{k}")
        if data:
            tags.add(f"OpcodeList{k}", UNDEFINED, bytes(data))
    if info.noise_profile is not None:
        noise = np.asarray(info.noise_profile, dtype=np.float64).ravel()
        if noise.size not in (2, 6) or np.any(noise < 0):
            raise DngError(tags.where, f"noise_profile must be 1 or 3 non-negative (S, O) pairs, got {noise.size} values")
        tags.add("NoiseProfile", DOUBLE, noise)


def write_dng_bytes(mosaic: np.ndarray, info: DngInfo, *, where="<dng bytes>", compression: str = "none") -> bytes:
    """The DNG file for an (H, W) uint16 Bayer mosaic and `info`, as bytes (deterministic).

    `mosaic` is the whole raw frame (`info.width`/`height` are ignored). `info` must pass
    `require_colour_tags` and `require_bayer_cfa`. `info.active_area` and the default crop are
    written only when they are not the whole frame, and must then fit the mosaic (else DngError).
    OpcodeLists are copied byte for byte: their regions must already suit the mosaic.
    `compression`: 'none' (one uncompressed strip) or 'ljpeg' (lossless JPEG tiles).
    """
    if compression not in COMPRESSIONS:
        raise DngError(where, f"unknown compression {compression!r} (choose from {', '.join(COMPRESSIONS)})")
    mosaic = np.asarray(mosaic)
    if mosaic.ndim != 2 or mosaic.shape[0] < 2 or mosaic.shape[1] < 2:
        raise DngError(where, f"mosaic must be a 2-D (H, W) array of at least 2x2, got shape {mosaic.shape}")
    if mosaic.dtype != np.uint16:
        if not np.issubdtype(mosaic.dtype, np.integer):
            raise DngError(where, f"mosaic must be uint16 digital numbers, got dtype {mosaic.dtype}")
        if mosaic.size and (mosaic.min() < 0 or mosaic.max() > 65535):
            raise DngError(where, "mosaic values outside 0..65535")
        mosaic = mosaic.astype(np.uint16)
    info_for_check = info if info.path else _with_path(info, where)
    require_bayer_cfa(info_for_check)
    require_colour_tags(info_for_check)
    extratags = _extratags(where, mosaic, info)

    import tifffile

    if compression == "ljpeg":
        from g2r_jax.io.lossless_jpeg import encode_tiles, precision_for, tile_shape

        tile = tile_shape(*mosaic.shape)
        data = dict(data=iter(encode_tiles(mosaic, precision_for(mosaic, info.white_level), tile)),
                    shape=mosaic.shape, dtype=np.uint16, bitspersample=16, compression=7, tile=tile)
    else:
        data = dict(data=np.ascontiguousarray(mosaic), compression=None, rowsperstrip=mosaic.shape[0])
    buffer = io.BytesIO()
    with tifffile.TiffWriter(buffer, byteorder="<", bigtiff=False) as tif:
        tif.write(
            **data,
            photometric=32803,              # CFA (TIFF/EP); DNG spec ch. 4 'PhotometricInterpretation'
            software=False,
            description=None,
            metadata=None,
            datetime=None,
            resolution=None,
            extratags=extratags,
        )
    return buffer.getvalue()


def _with_path(info: DngInfo, where) -> DngInfo:
    import dataclasses
    return dataclasses.replace(info, path=str(where))


def write_dng(path, mosaic: np.ndarray, info: DngInfo, *, compression: str = "none") -> None:
    """Write `mosaic` and `info` as a DNG at `path`, atomically and deterministically.

    The bytes of `write_dng_bytes` go to a temporary file '.<name>.<random>.tmp' in the target's
    folder, which is flushed, fsync'ed and `os.replace`d onto `path`; on any failure the
    temporary file is removed and `path` is left as it was. Errors are `DngError(path, ...)`.
    `compression`: as in `write_dng_bytes`.
    """
    path = Path(path)
    data = write_dng_bytes(mosaic, info, where=path, compression=compression)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise DngError(path, "output folder does not exist")
    try:
        atomic_write_bytes(path, data)
    except OSError as exc:
        raise DngError(path, f"cannot write ({exc.strerror or exc})") from exc
