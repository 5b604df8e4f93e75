"""Reading DNG tags (tifffile) and CFA pixels (LibRaw via rawpy).

References are to Adobe, *Digital Negative (DNG) Specification* 1.6 (2020): "spec ch. 4 'X'" is
the entry for tag X in its tag chapter, "spec 'Colour'" its chapter "Mapping Camera Color Space to
CIE XYZ Space", "spec 'SubIFD Trees'" that section of ch. 2. Tag values are read
with tifffile only, so a file whose pixels no decoder can read still yields its tags: those are all
a sensor profile needs.

Where the tags live (spec 'SubIFD Trees'): the raw image is the IFD with NewSubFileType 0,
either IFD0 itself (e.g. GoPro files) or one of IFD0's SubIFDs (Adobe DNG Converter files, whose
IFD0 holds a preview). Raw-IFD tags (CFA layout, BlackLevel, WhiteLevel, ActiveArea, DefaultCrop*,
OpcodeList*) are looked up in the raw IFD first, then IFD0; colour tags (ColorMatrix*, AsShotNeutral,
...) in IFD0 first, then the raw IFD.
"""

from __future__ import annotations

import contextlib
import logging
import math
import re
import threading
import warnings
from pathlib import Path
from typing import Optional

import numpy as np

from g2r_jax.io.dng_info import DngError, DngInfo
from g2r_jax.io.illuminant_data import parse_illuminant_data
from g2r_jax.io.pixel_layout import bits_problem, decoded_finding, layout_problem, stored_values_problem
from g2r_jax.io.raw_compression import undecodable_reason
from g2r_jax.io.tag_checks import check_dng_tags

__all__ = ["read_dng_info", "read_dng_pixels", "require_colour_tags", "require_bayer_cfa", "TAGS"]

# Tag codes used here (spec ch. 4; TIFF 6.0 and TIFF/EP for the baseline ones; EXIF 2.3 for ISO).
TAGS = {
    "NewSubfileType": 254,
    "ImageWidth": 256,
    "ImageLength": 257,
    "BitsPerSample": 258,
    "Compression": 259,
    "PhotometricInterpretation": 262,
    "Make": 271,
    "Model": 272,
    "StripOffsets": 273,
    "Orientation": 274,
    "SamplesPerPixel": 277,
    "RowsPerStrip": 278,
    "StripByteCounts": 279,
    "PlanarConfiguration": 284,
    "TileWidth": 322,
    "TileLength": 323,
    "TileOffsets": 324,
    "TileByteCounts": 325,
    "SubIFDs": 330,
    "CFARepeatPatternDim": 33421,
    "CFAPattern": 33422,
    "ExposureTime": 33434,
    "ExifIFD": 34665,
    "ISOSpeedRatings": 34855,
    "DNGVersion": 50706,
    "DNGBackwardVersion": 50707,
    "UniqueCameraModel": 50708,
    "CFAPlaneColor": 50710,
    "CFALayout": 50711,
    "LinearizationTable": 50712,
    "BlackLevelRepeatDim": 50713,
    "BlackLevel": 50714,
    "BlackLevelDeltaH": 50715,
    "BlackLevelDeltaV": 50716,
    "WhiteLevel": 50717,
    "DefaultCropOrigin": 50719,
    "DefaultCropSize": 50720,
    "ColorMatrix1": 50721,
    "ColorMatrix2": 50722,
    "CameraCalibration1": 50723,
    "CameraCalibration2": 50724,
    "AnalogBalance": 50727,
    "AsShotNeutral": 50728,
    "AsShotWhiteXY": 50729,
    "BaselineExposure": 50730,
    "CalibrationIlluminant1": 50778,
    "CalibrationIlluminant2": 50779,
    "ActiveArea": 50829,
    "ForwardMatrix1": 50964,
    "ForwardMatrix2": 50965,
    "OpcodeList1": 51008,
    "OpcodeList2": 51009,
    "OpcodeList3": 51022,
    "NoiseProfile": 51041,
    "CalibrationIlluminant3": 52529,   # DNG 1.6
    "CameraCalibration3": 52530,
    "ColorMatrix3": 52531,
    "ForwardMatrix3": 52532,
    "IlluminantData1": 52533,
    "IlluminantData2": 52534,
    "IlluminantData3": 52535,
}

PHOTOMETRIC_CFA = 32803
PHOTOMETRIC_LINEAR_RAW = 34892
_RATIONAL_TYPES = (5, 10)          # TIFF RATIONAL, SRATIONAL


# ----------------------------------------------------------------------------- tag helpers

def _tag(page, name):
    """The TiffTag `name` of one IFD, or None."""
    if page is None:
        return None
    return page.tags.get(TAGS[name])


def _floats(path, tag, name) -> np.ndarray:
    """A numeric tag as a flat float64 array; (S)RATIONAL pairs become num/den."""
    value = tag.value
    if isinstance(value, (bytes, bytearray)):
        arr = np.frombuffer(bytes(value), dtype=np.uint8).astype(np.float64)
    else:
        arr = np.atleast_1d(np.asarray(value, dtype=np.float64)).ravel()
    if int(tag.dtype) in _RATIONAL_TYPES:
        if arr.size % 2:
            raise DngError(path, f"tag {name} has an odd number of rational parts")
        num, den = arr[0::2], arr[1::2]
        if np.any(den == 0):
            raise DngError(path, f"tag {name} has a zero denominator")
        arr = num / den
    if not np.all(np.isfinite(arr)):
        raise DngError(path, f"tag {name} holds non-finite values")
    return arr


def _ints(path, tag, name) -> tuple:
    vals = _floats(path, tag, name)
    return tuple(int(round(v)) for v in vals)


def _text(tag) -> str:
    value = tag.value
    if isinstance(value, (bytes, bytearray)):
        value = bytes(value).decode("latin-1")
    return str(value).split("\x00", 1)[0].strip()


def _raw_bytes(tag) -> bytes:
    value = tag.value
    if isinstance(value, (bytes, bytearray)):
        return bytes(value)
    return bytes(np.asarray(value, dtype=np.uint8).ravel())


def _find_raw_ifd(tif):
    """The main raw IFD (NewSubFileType 0, spec ch. 4 'NewSubFileType') in IFD0's chain or SubIFDs."""
    top = []
    page = tif.pages.first
    top.append(page)
    # Further top-level IFDs are rare in DNGs; look at the next few only.
    for i in range(1, 4):
        try:
            top.append(tif.pages[i])
        except IndexError:
            break
        except Exception:  # a damaged IFD chain past IFD0 is not fatal: IFD0 holds the DNG tags
            break
    candidates = []
    for page in top:
        candidates.append(page)
        subs = getattr(page, "pages", None)
        if subs is not None:
            try:
                candidates.extend(list(subs))
            except Exception:
                pass
    for page in candidates:
        tag = _tag(page, "NewSubfileType")
        subtype = int(tag.value) if tag is not None else 0
        photometric = int(page.photometric) if page.photometric is not None else -1
        if subtype == 0 and photometric in (PHOTOMETRIC_CFA, PHOTOMETRIC_LINEAR_RAW):
            return page
    for page in candidates:  # no CFA/LinearRaw main image: fall back to any NewSubFileType 0 IFD
        tag = _tag(page, "NewSubfileType")
        if tag is None or int(tag.value) == 0:
            return page
    return None


def _expand_black(path, black, repeat, deltas_h, deltas_v, samples) -> np.ndarray:
    """Black level per 2x2 tile position (spec ch. 4 'BlackLevel', 'BlackLevelRepeatDim').

    BlackLevel holds rows*cols*SamplesPerPixel values for a repeat pattern whose origin is the
    ActiveArea's top-left corner. The pattern is tiled to a common multiple of 2 and averaged per
    tile position (row parity, column parity); samples are averaged (LinearRaw only). The means
    of BlackLevelDeltaV (per row) and BlackLevelDeltaH (per column) of the same parity are added.
    """
    rows, cols = repeat
    if rows < 1 or cols < 1 or rows * cols > 4096:
        raise DngError(path, f"BlackLevelRepeatDim {rows}x{cols} is not a usable repeat pattern")
    per_position = samples
    if black.size != rows * cols * samples:
        # Some phones (e.g. Samsung) write 12 values for a 2x2 repeat and SamplesPerPixel 1. Read
        # in the spec's row-column-sample order (3 per position) or as LibRaw reads them (the first
        # rows x cols), they mean the same only when both readings agree; then they are used,
        # otherwise the file is refused: the pixels' black level would be a guess.
        extra = black.size // (rows * cols) if black.size % (rows * cols) == 0 else 0
        if samples != 1 or extra not in (2, 3, 4) or not np.allclose(
                black.reshape(rows * cols, extra).mean(axis=1), black[: rows * cols], atol=0.5):
            raise DngError(path, f"BlackLevel has {black.size} values, expected "
                                 f"{rows}x{cols}x{samples} (BlackLevelRepeatDim x SamplesPerPixel)")
        per_position = extra
    grid = black.reshape(rows, cols, per_position).mean(axis=2)
    big = np.tile(grid, (math.lcm(rows, 2) // rows, math.lcm(cols, 2) // cols))
    out = np.empty(4)
    for i in range(2):
        for j in range(2):
            out[2 * i + j] = big[i::2, j::2].mean()
    if deltas_v is not None and deltas_v.size:
        for i in range(2):
            part = deltas_v[i::2]
            if part.size:
                out[2 * i: 2 * i + 2] += part.mean()
    if deltas_h is not None and deltas_h.size:
        for j in range(2):
            part = deltas_h[j::2]
            if part.size:
                out[j::2] += part.mean()
    return out


# ----------------------------------------------------------------------------- public API

def read_dng_info(path) -> DngInfo:
    """Read the tags of a DNG into a `DngInfo` (tifffile only, pixels are not decoded).

    Raises `DngError(path, problem)` for a missing file, a file that is not TIFF (e.g. text renamed
    .dng), a TIFF without DNGVersion (spec ch. 4 'DNGVersion': required in IFD0), a header cut
    short, malformed tags, or no raw IFD. A file whose raw pixel data is short or missing but whose
    tags are complete returns normally, with the problem in `info.pixel_data_problem` and
    `info.warnings`; `read_dng_pixels` then raises. Pixel data that contradicts its tags (byte
    counts that do not match width x rows x BitsPerSample, segments lying on the file's header or
    tags, a BitsPerSample that cannot hold the WhiteLevel: `g2r_jax.io.pixel_layout`) raises:
    such tags cannot be trusted. Missing colour tags are *not* an error here:
    see `require_colour_tags`; LinearRaw or non-Bayer CFAs neither: see `require_bayer_cfa`.

    Conventions: matrices 3x3 float64; `cfa_pattern` colour indices 0=R, 1=G, 2=B mapped through
    CFAPlaneColor, row-major over the CFARepeatPatternDim tile (origin: ActiveArea's top-left
    corner, spec ch. 4 'ActiveArea'); `black_level` per 2x2 tile position; `default_crop_origin`
    and `default_crop_size` as stored, i.e. (horizontal, vertical) = (x, y) / (width, height),
    relative to the ActiveArea; `active_area` as (top, left, bottom, right).
    """
    import tifffile

    path = Path(path)
    if not path.exists():
        raise DngError(path, "file not found")
    if not path.is_file():
        raise DngError(path, "not a regular file")
    file_size = path.stat().st_size
    if file_size < 8:
        raise DngError(path, f"file too short to be a DNG ({file_size} bytes)")
    try:
        with _library_log(path) as library_messages, tifffile.TiffFile(str(path)) as tif:
            info = _parse(path, tif, file_size)
        if library_messages and not info.warnings:
            info.warnings.append(f"TIFF structure partly damaged ({_short(_plain(library_messages[0]))})")
        return check_dng_tags(info)
    except DngError:
        raise
    except tifffile.TiffFileError as exc:
        with open(path, "rb") as handle:
            magic = handle.read(4)
        if magic in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
            raise DngError(path, f"TIFF structure damaged or truncated ({_short(_plain(exc))})") from exc
        raise DngError(path, f"not a TIFF/DNG file ({_short(_plain(exc))})") from exc
    except Exception as exc:  # tifffile raises many kinds on damaged files (struct.error, ...)
        raise DngError(path, "cannot parse DNG tags, file damaged or truncated "
                             f"({_short(_plain(exc))})") from exc


class _LogCollector(logging.Handler):
    """tifffile's log records, each kept by the reader of the thread that caused it (they would
    print to stderr). One collector for the process, installed while any thread reads: readers on
    several threads each saving and restoring the logger's state left it without propagation and
    without handler, and tifffile's records reached stderr raw (g2r-diagnose, whose DNGs are
    read on threads)."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.lock = threading.Lock()
        self.readers, self.saved_propagate = {}, True   # thread id -> its list of messages

    def emit(self, record):
        messages = self.readers.get(record.thread)
        if messages is None:   # a thread that is not reading a DNG: its record goes where it would have
            if self.saved_propagate:
                logging.getLogger().handle(record)
        elif record.levelno >= logging.WARNING:
            messages.append(record.getMessage())


_COLLECTOR = _LogCollector()


@contextlib.contextmanager
def _library_log(path):
    """tifffile logs damage it skips over (e.g. '<tifffile.TiffPages @1712> invalid offset to
    first page'); those records become (at most) one warning of ours naming the file."""
    logger = logging.getLogger("tifffile")
    thread, messages = threading.get_ident(), []
    with _COLLECTOR.lock:
        if not _COLLECTOR.readers:
            _COLLECTOR.saved_propagate = logger.propagate
            logger.addHandler(_COLLECTOR)
            logger.propagate = False
        outer = _COLLECTOR.readers.get(thread)
        _COLLECTOR.readers[thread] = messages
    try:
        yield messages
    finally:
        with _COLLECTOR.lock:
            if outer is None:
                del _COLLECTOR.readers[thread]
            else:
                _COLLECTOR.readers[thread] = outer
            if not _COLLECTOR.readers:
                logger.removeHandler(_COLLECTOR)
                logger.propagate = _COLLECTOR.saved_propagate


def _plain(message) -> str:
    """A tifffile message in our words: '<tifffile.TiffTag 50717 @310> invalid value offset 16383'
    becomes 'tag 50717: invalid value offset 16383'; other '<...>' object names are dropped."""
    text = str(message)
    found = re.search(r"TiffTag (\d+) @\d+>\s*([^'\"]*)", text)
    if found:
        return f"tag {found.group(1)}: {found.group(2).strip()}"
    text = re.sub(r"<[^<>]*>\s*", "", text)
    text = re.sub(r"\w+\.fromfile|raised \w+Error\(|TiffFileError\(?", "", text)
    return text.strip(" ()'\"") or "unreadable structure"


def _short(exc) -> str:
    text = " ".join(str(exc).split())
    return (text[:160] + "...") if len(text) > 160 else (text or type(exc).__name__)


class _Ifds:
    """The raw IFD and IFD0 of one DNG, and where each kind of tag is looked up first (module
    note: raw-IFD tags in the raw IFD, then IFD0; colour tags in IFD0, then the raw IFD)."""

    def __init__(self, path: Path, ifd0, raw):
        self.path, self.ifd0, self.raw = path, ifd0, raw

    def raw_first(self, name):
        tag = _tag(self.raw, name)
        return tag if tag is not None else _tag(self.ifd0, name)

    def ifd0_first(self, name):
        tag = _tag(self.ifd0, name)
        return tag if tag is not None else _tag(self.raw, name)

    def matrix(self, name, *, required_size_note: str = "expected 9"):
        """A 3x3 matrix tag (IFD0 first), or None when absent."""
        tag = self.ifd0_first(name)
        if tag is None:
            return None
        values = _floats(self.path, tag, name)
        if values.size != 9:
            raise DngError(self.path, f"{name} has {values.size} values, {required_size_note}")
        return values.reshape(3, 3)


def _parse(path: Path, tif, file_size: int) -> DngInfo:
    """Every tag g2r_jax uses, from an open TiffFile, into a DngInfo; then the pixel data's
    layout against the tags (g2r_jax.io.pixel_layout)."""
    ifd0 = tif.pages.first
    version_tag = _tag(ifd0, "DNGVersion")
    if version_tag is None:
        raise DngError(path, "not a DNG (TIFF without the DNGVersion tag)")
    version = tuple(int(v) for v in _raw_bytes(version_tag)[:4])
    raw = _find_raw_ifd(tif)
    if raw is None:
        raise DngError(path, "DNG has no main raw image IFD (NewSubFileType 0)")
    info = DngInfo(path=str(path), dng_version=version)
    ifds = _Ifds(path, ifd0, raw)
    info.width, info.height = int(raw.imagewidth), int(raw.imagelength)
    info.photometric = int(raw.photometric)
    info.is_cfa = info.photometric == PHOTOMETRIC_CFA
    bps = raw.bitspersample
    info.bits_per_sample = int(np.max(np.atleast_1d(bps))) if bps else 16
    _read_cfa(info, ifds)
    _read_levels(info, ifds, int(raw.samplesperpixel or 1))
    for attr, name in (("unique_camera_model", "UniqueCameraModel"), ("make", "Make"), ("model", "Model")):
        tag = ifds.ifd0_first(name)
        if tag is not None:
            setattr(info, attr, _text(tag))
    _read_colour(info, ifds, tif.byteorder)
    _read_white_balance(info, ifds)
    _read_exposure(info, ifds)
    _read_geometry(info, ifds)
    _check_pixel_layout(info, raw, (ifd0, raw), tif.filehandle, tif.byteorder, file_size)
    return info


def _read_cfa(info: DngInfo, ifds: _Ifds) -> None:
    """CFA layout (spec ch. 4 'CFARepeatPatternDim', 'CFAPattern', 'CFAPlaneColor')."""
    path, raw = ifds.path, ifds.raw
    if not info.is_cfa:
        info.cfa_pattern, info.cfa_repeat_dim = (), ()
        return
    dim_tag, pat_tag = _tag(raw, "CFARepeatPatternDim"), _tag(raw, "CFAPattern")
    if pat_tag is None:
        raise DngError(path, "CFA raw image without a CFAPattern tag")
    dims = _ints(path, dim_tag, "CFARepeatPatternDim") if dim_tag is not None else (2, 2)
    if len(dims) != 2 or dims[0] < 1 or dims[1] < 1:
        raise DngError(path, f"bad CFARepeatPatternDim {dims}")
    pattern = _raw_bytes(pat_tag)
    if len(pattern) != dims[0] * dims[1]:
        raise DngError(path, f"CFAPattern has {len(pattern)} entries, expected {dims[0]}x{dims[1]}")
    plane_tag = _tag(raw, "CFAPlaneColor")
    planes = tuple(_raw_bytes(plane_tag)) if plane_tag is not None else (0, 1, 2)
    try:
        info.cfa_pattern = tuple(int(planes[p]) for p in pattern)
    except IndexError:
        raise DngError(path, f"CFAPattern {tuple(pattern)} refers to planes beyond "
                             f"CFAPlaneColor {planes}") from None
    info.cfa_repeat_dim = (int(dims[0]), int(dims[1]))


def _read_levels(info: DngInfo, ifds: _Ifds, samples: int) -> None:
    """Black and white levels (spec ch. 4 'BlackLevel', 'BlackLevelDeltaH/V', 'WhiteLevel',
    'LinearizationTable')."""
    path = ifds.path
    black_tag, rep_tag = ifds.raw_first("BlackLevel"), ifds.raw_first("BlackLevelRepeatDim")
    repeat = _ints(path, rep_tag, "BlackLevelRepeatDim") if rep_tag is not None else (1, 1)
    if len(repeat) != 2:
        raise DngError(path, f"bad BlackLevelRepeatDim {repeat}")
    black = (_floats(path, black_tag, "BlackLevel") if black_tag is not None
             else np.zeros(repeat[0] * repeat[1] * samples))
    dh, dv = ifds.raw_first("BlackLevelDeltaH"), ifds.raw_first("BlackLevelDeltaV")
    info.black_level = _expand_black(
        path, black, repeat,
        _floats(path, dh, "BlackLevelDeltaH") if dh is not None else None,
        _floats(path, dv, "BlackLevelDeltaV") if dv is not None else None,
        samples)
    # LinearizationTable (spec ch. 4): stored values index the table; BlackLevel and WhiteLevel are
    # in the linearised values (LibRaw applies the table when decoding, see read_dng_pixels).
    table_tag = ifds.raw_first("LinearizationTable")
    if table_tag is not None:
        table = _floats(path, table_tag, "LinearizationTable")
        if not 1 <= table.size <= 65536 or np.min(table) < 0 or np.max(table) > 65535:
            raise DngError(path, f"LinearizationTable: {table.size} entries, values must lie in 0..65535")
        info.linearization_table = table
    white_tag = ifds.raw_first("WhiteLevel")
    if white_tag is not None:
        whites = _floats(path, white_tag, "WhiteLevel")
        info.white_level = float(whites.max())
        if whites.size > 1 and np.ptp(whites) > 0:
            info.warnings.append(f"WhiteLevel differs per sample ({whites.min():g} to {whites.max():g}); "
                                 "using the largest")
    elif table_tag is not None:  # linearised values cannot exceed the table
        info.white_level = float(np.max(info.linearization_table))
    else:  # spec default: 2 ** BitsPerSample - 1
        info.white_level = float(2 ** info.bits_per_sample - 1)


def _read_colour(info: DngInfo, ifds: _Ifds, byteorder: str) -> None:
    """Colour matrices and their illuminants (spec ch. 4 'ColorMatrix1'..'ForwardMatrix3',
    'IlluminantData1..3'; spec 'Colour' for their use)."""
    path = ifds.path
    illuminants, matrices, calibrations, forwards, whites = [], [], [], [], []
    for k in (1, 2, 3):
        if ifds.ifd0_first(f"ColorMatrix{k}") is None:
            continue
        matrices.append(ifds.matrix(f"ColorMatrix{k}", required_size_note="only 3-colour cameras "
                                                                          "(9 values) are supported"))
        ill = ifds.ifd0_first(f"CalibrationIlluminant{k}")
        illuminants.append(_ints(path, ill, f"CalibrationIlluminant{k}")[0] if ill is not None else 0)
        calibrations.append(ifds.matrix(f"CameraCalibration{k}"))
        forwards.append(ifds.matrix(f"ForwardMatrix{k}"))
        data = ifds.ifd0_first(f"IlluminantData{k}") if illuminants[-1] == 255 else None
        if data is not None:   # DNG 1.6: the white of an 'other' (255) illuminant
            try:
                whites.append(tuple(parse_illuminant_data(_raw_bytes(data), byteorder)))
            except ValueError as error:
                raise DngError(path, f"IlluminantData{k}: {error}") from None
        else:
            whites.append(None)
    info.calibration_illuminants = tuple(illuminants)
    if any(w is not None for w in whites):
        info.illuminant_data = tuple(whites)
    info.color_matrices = tuple(matrices)
    if any(c is not None for c in calibrations):   # spec default for a missing one: identity
        info.camera_calibrations = tuple(np.eye(3) if c is None else c for c in calibrations)
    if all(f is not None for f in forwards) and forwards:
        info.forward_matrices = tuple(forwards)
    elif any(f is not None for f in forwards):
        info.warnings.append("ForwardMatrix present for some calibration illuminants only; ignored")


def _read_white_balance(info: DngInfo, ifds: _Ifds) -> None:
    """AnalogBalance, AsShotNeutral, AsShotWhiteXY, BaselineExposure, NoiseProfile (spec ch. 4)."""
    path = ifds.path
    for attr, name, n in (("analog_balance", "AnalogBalance", 3), ("as_shot_neutral", "AsShotNeutral", 3),
                          ("as_shot_white_xy", "AsShotWhiteXY", 2)):
        tag = ifds.ifd0_first(name)
        if tag is not None:
            vals = _floats(path, tag, name)
            if vals.size != n:
                raise DngError(path, f"{name} has {vals.size} values, expected {n}")
            setattr(info, attr, vals)
    if info.as_shot_neutral is not None and np.any(info.as_shot_neutral <= 0):
        raise DngError(path, f"AsShotNeutral {tuple(info.as_shot_neutral)} has non-positive values")
    tag = ifds.ifd0_first("BaselineExposure")
    if tag is not None:
        info.baseline_exposure = float(_floats(path, tag, "BaselineExposure")[0])
    tag = ifds.raw_first("NoiseProfile")
    if tag is not None:
        vals = _floats(path, tag, "NoiseProfile")
        if vals.size < 2 or vals.size % 2:
            raise DngError(path, f"NoiseProfile has {vals.size} values, expected pairs")
        info.noise_profile = vals.reshape(-1, 2)


def _read_exposure(info: DngInfo, ifds: _Ifds) -> None:
    """ISO and exposure time (EXIF 2.3 ISOSpeedRatings 34855 / ExposureTime 33434; in IFD0 per
    TIFF/EP, or in the EXIF IFD)."""
    path = ifds.path
    exif = _tag(ifds.ifd0, "ExifIFD")
    exif = exif.value if exif is not None and isinstance(exif.value, dict) else {}
    tag = ifds.ifd0_first("ISOSpeedRatings")
    if tag is not None:
        info.iso = float(_floats(path, tag, "ISOSpeedRatings")[0])
    elif exif.get("ISOSpeedRatings") is not None:
        info.iso = float(np.atleast_1d(exif["ISOSpeedRatings"])[0])
    tag = ifds.ifd0_first("ExposureTime")
    if tag is not None:
        info.exposure_time = float(_floats(path, tag, "ExposureTime")[0])
    elif exif.get("ExposureTime") is not None:
        value = np.atleast_1d(np.asarray(exif["ExposureTime"], dtype=np.float64))
        if value.size == 2 and value[1] != 0:
            info.exposure_time = float(value[0] / value[1])
        elif value.size == 1:
            info.exposure_time = float(value[0])


def _read_geometry(info: DngInfo, ifds: _Ifds) -> None:
    """ActiveArea, DefaultCropOrigin/Size and the opcode lists (spec ch. 4, ch. 7)."""
    path = ifds.path
    tag = ifds.raw_first("ActiveArea")
    if tag is not None:
        area = _ints(path, tag, "ActiveArea")
        if len(area) != 4 or not (0 <= area[0] < area[2] <= info.height and 0 <= area[1] < area[3] <= info.width):
            raise DngError(path, f"ActiveArea {area} does not fit the {info.width}x{info.height} raw image")
        info.active_area = area
    for attr, name in (("default_crop_origin", "DefaultCropOrigin"), ("default_crop_size", "DefaultCropSize")):
        tag = ifds.raw_first(name)
        if tag is not None:
            vals = _floats(path, tag, name)
            if vals.size != 2:
                raise DngError(path, f"{name} has {vals.size} values, expected 2")
            setattr(info, attr, tuple(float(v) for v in vals))
    for k in (1, 2, 3):
        tag = ifds.raw_first(f"OpcodeList{k}")
        if tag is not None:
            info.opcode_lists[f"OpcodeList{k}"] = _raw_bytes(tag)


def _check_pixel_layout(info: DngInfo, raw, pages, handle, byteorder: str, file_size: int) -> None:
    """Refuse tags that contradict the pixel data; note pixel data that is missing or that this
    LibRaw cannot decode (tags still usable: `info.pixel_data_problem`)."""
    info.compression = int(raw.compression)
    found = layout_problem(raw, pages, handle, file_size, byteorder)
    refusal = found.refusal or bits_problem(info.bits_per_sample, info.white_level,
                                            info.linearization_table is not None)
    if refusal is None and found.warning is None and info.linearization_table is None:
        refusal = stored_values_problem(raw, handle, byteorder, info.white_level)
    if refusal is not None:
        raise DngError(info.path, refusal)
    problem = undecodable_reason(info.compression) or found.warning
    if problem is not None:
        info.pixel_data_problem = problem
        info.warnings.append(problem)


def require_colour_tags(info: DngInfo) -> DngInfo:
    """Raise `DngError` unless `info` has what colour fitting needs; return `info` otherwise.

    Needs ColorMatrix1 (spec ch. 4: required for all non-monochrome DNGs), a known
    CalibrationIlluminant for each matrix when there are two or more (spec 'Colour' interpolates
    between them by correlated colour temperature), and invertible matrices.
    """
    if not info.color_matrices:
        raise DngError(info.path, "no ColorMatrix tags: cannot map camera RGB to XYZ")
    for k, m in enumerate(info.color_matrices, start=1):
        m = np.asarray(m, dtype=np.float64)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)) or abs(np.linalg.det(m)) < 1e-12:
            raise DngError(info.path, f"ColorMatrix{k} is not an invertible 3x3 matrix")
    if len(info.color_matrices) != len(info.calibration_illuminants):
        raise DngError(info.path, "ColorMatrix and CalibrationIlluminant counts differ")
    if len(info.color_matrices) > 1 and 0 in info.calibration_illuminants:
        raise DngError(info.path, "several ColorMatrix tags but a CalibrationIlluminant is "
                                  "missing or 0 (unknown): cannot interpolate between them")
    data = tuple(info.illuminant_data) + (None,) * len(info.calibration_illuminants)
    for k, code in enumerate(info.calibration_illuminants, start=1):
        if code == 255 and data[k - 1] is None:
            raise DngError(info.path, f"CalibrationIlluminant{k} is 255 (other) but IlluminantData{k} is missing")
    return info


def require_bayer_cfa(info: DngInfo) -> DngInfo:
    """Raise `DngError` unless the raw image is a 2x2 Bayer CFA (one R, two G, one B); return `info`.

    LinearRaw (PhotometricInterpretation 34892, spec ch. 4 'PhotometricInterpretation') is already
    demosaiced and has no CFA; X-Trans (6x6) and CMY/RGBE patterns do not fit the 2x2 model.
    """
    if not info.is_cfa:
        kind = "LinearRaw (already demosaiced)" if info.photometric == PHOTOMETRIC_LINEAR_RAW else \
            f"PhotometricInterpretation {info.photometric}"
        raise DngError(info.path, f"raw image is {kind}, not a Bayer CFA mosaic")
    dims = tuple(getattr(info, "cfa_repeat_dim", (2, 2)) or (2, 2))
    pattern = tuple(int(c) for c in info.cfa_pattern)
    if dims != (2, 2) or len(pattern) != 4 or sorted(pattern) != [0, 1, 1, 2]:
        raise DngError(info.path, f"CFA pattern {pattern} over {dims} is not a 2x2 Bayer pattern "
                                  "(one R, two G, one B)")
    return info


def read_dng_pixels(path, info: Optional[DngInfo] = None) -> np.ndarray:
    """The CFA mosaic of a Bayer DNG as an (H, W) array, decoded by LibRaw (rawpy).

    Crop choice: LibRaw's full `raw_image` is cropped to the ActiveArea from the tags (the whole
    image when absent), *not* to DefaultCrop. This is exactly the region to which the DNG's
    CFAPattern and BlackLevel repeat patterns are anchored (spec ch. 4 'ActiveArea'), so pixel
    (0, 0) has colour `info.cfa_pattern[0]`; this is checked against LibRaw's own colour map.
    Values are as stored (LibRaw applies a LinearizationTable if present), dtype uint16; no black
    subtraction, no OpcodeList processing.

    Raises `DngError` naming the file for: non-Bayer or LinearRaw files, pixel data found missing
    or truncated by the structural check of `read_dng_info` (LibRaw itself would silently return
    zeros), anything LibRaw refuses to decode, a decoded frame smaller than the tagged size, and
    a decoded raster its tags cannot describe (`pixel_layout.decoded_finding`: most pixels above
    WhiteLevel, a constant raster outside black..white, zeros where the black level is high, green
    sites out of phase with the CFAPattern by two agreeing tests). What that check only suspects
    (one of the two phase tests) is added to `info.warnings` and issued as a `UserWarning` naming
    the file (the commands print it as one line), and the pixels are returned.
    """
    import rawpy

    path = Path(path)
    if info is None:
        info = read_dng_info(path)
    require_bayer_cfa(info)
    problem = getattr(info, "pixel_data_problem", None)
    if problem:
        raise DngError(path, problem)
    from g2r_jax.io.native_stderr import captured_native_stderr

    try:   # LibRaw may print its own complaints about damaged data: the DngError below says it
        with captured_native_stderr(lambda line: not line.startswith("g2r-")), rawpy.imread(str(path)) as raw:
            full = raw.raw_image
            colours = raw.raw_colors
            desc = raw.color_desc.decode("ascii", "replace")
            if full.ndim != 2:
                raise DngError(path, f"LibRaw decoded a {full.ndim}-D image, not a CFA mosaic")
            if full.shape == (info.height, info.width):
                top, left, bottom, right = info.active_area or (0, 0, info.height, info.width)
                mosaic = np.array(full[top:bottom, left:right], copy=True)
                tile = colours[top:top + 2, left:left + 2]
            elif full.shape[0] < info.height or full.shape[1] < info.width:
                raise DngError(path, f"LibRaw decoded a {full.shape[1]}x{full.shape[0]} raw frame, the tags say "
                                     f"{info.width}x{info.height}: the pixel data does not match its tags")
            else:  # LibRaw padded the raw frame: its visible area is the active one
                vis = raw.raw_image_visible
                mosaic = np.array(vis, copy=True)
                s = raw.sizes
                tile = colours[s.top_margin:s.top_margin + 2, s.left_margin:s.left_margin + 2]
                if info.active_area is not None:
                    t, l, b, r = info.active_area
                    if mosaic.shape != (b - t, r - l):
                        raise DngError(path, f"LibRaw's raw frame {full.shape} and visible area "
                                             f"{mosaic.shape} disagree with ActiveArea {info.active_area}")
    except DngError:
        raise
    except Exception as exc:  # rawpy.LibRawError and its subclasses, MemoryError, ...
        raise DngError(path, f"LibRaw cannot decode the pixels ({type(exc).__name__}: {_short(exc)})") from exc
    letters = {"R": 0, "G": 1, "B": 2}
    try:
        libraw_pattern = tuple(letters[desc[int(c)]] for c in np.asarray(tile).ravel())
    except (KeyError, IndexError):
        libraw_pattern = None
    if libraw_pattern is not None and libraw_pattern != tuple(info.cfa_pattern):
        raise DngError(path, f"LibRaw's CFA colours {libraw_pattern} at the active-area origin "
                             f"disagree with the CFAPattern tag {tuple(info.cfa_pattern)}")
    found = decoded_finding(mosaic, info.black_level, info.white_level, info.cfa_pattern)
    if found.refusal is not None:
        raise DngError(path, found.refusal)
    if found.warning is not None and found.warning not in info.warnings:
        info.warnings.append(found.warning)
        warnings.warn(f"{path}: {found.warning}", stacklevel=2)   # the commands print it as one line
    return mosaic
