"""Decoding computer-graphics images: PNG, JPEG, TIFF (sRGB-encoded) and OpenEXR (linear).

`read_image` returns float32 (H, W, 3) values and the encoding they are in: 'srgb' for PNG, JPEG
and TIFF, whose 8- or 16-bit code values are only scaled to [0, 1] (decoding the sRGB transfer
function is the caller's job, e.g. with a look-up table on `read_image_uint8`'s output), and
'linear' for EXR. Alpha is dropped, grey becomes three equal channels, odd sizes are kept.
Every unreadable input raises `DngError(path, problem)`, the project's generic file error.

Before any decoding, the size the header claims is checked against a pixel budget of our own
(`max_pixels`, 100 megapixels by default; the command's `--max-megapixels`), and a PNG's data is
checked to hold every row it claims (`g2r_jax.io.image_headers`): memory follows the file's real
data, and a truncated image is refused by name instead of being padded with zeros.

Decoders: libspng (through imagecodecs) for 8-bit grey, RGB, RGBA and palette PNGs, about twice
as fast as Pillow and silent on stderr (libpng's own decoder prints warnings there); Pillow for
other PNGs, for any PNG libspng refuses (so that its refusal gets our message) and for JPEG; tifffile for TIFF (Pillow as a fallback for compressions
tifffile cannot decode without imagecodecs, e.g. LZW, except 16-bit colour, which Pillow would cut
to 8 bits), the OpenEXR package's `OpenEXR.File` API for EXR.
Pillow reduces 16-bit colour PNGs to 8 bits; the full 16 bits are recovered by decoding the
same stream a second time with Pillow's little-endian unpacker, which then picks the low bytes
(PNG stores samples big-endian, PNG spec 2nd ed. section 7.1), using its own unfiltering.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterable, Optional, Union

import numpy as np

from g2r_jax.io.dng_info import DngError
from g2r_jax.io.image_headers import (DEFAULT_MAX_PIXELS, PNG_SIGNATURE, check_pixel_budget, check_png_complete,
                                      check_jpeg_complete, png_claim)

__all__ = ["read_image", "read_image_uint8", "read_images", "list_inputs", "DEFAULT_MAX_PIXELS",
           "SRGB_EXTENSIONS", "EXR_EXTENSIONS", "IMAGE_EXTENSIONS"]

SRGB_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff")
EXR_EXTENSIONS = (".exr",)
IMAGE_EXTENSIONS = SRGB_EXTENSIONS + EXR_EXTENSIONS

PathLike = Union[str, Path]


def _short(exc) -> str:
    text = " ".join(str(exc).split())
    return (text[:160] + "...") if len(text) > 160 else (text or type(exc).__name__)


def _check_file(path: Path) -> str:
    if not path.exists():
        raise DngError(path, "file not found")
    if not path.is_file():
        raise DngError(path, "not a regular file")
    ext = path.suffix.lower()
    if ext not in IMAGE_EXTENSIONS:
        raise DngError(path, f"unsupported image type '{ext}' (supported: {', '.join(IMAGE_EXTENSIONS)})")
    return ext


def _to_rgb(arr: np.ndarray, path: Path) -> np.ndarray:
    """(H, W), (H, W, 1..4) -> (H, W, 3): grey replicated, alpha dropped."""
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[2] < 1:
        raise DngError(path, f"unexpected image array shape {arr.shape}")
    if arr.shape[2] in (1, 2):            # grey, grey + alpha
        arr = np.repeat(arr[:, :, :1], 3, axis=2)
    elif arr.shape[2] >= 3:               # RGB, RGBA, RGB + extra samples
        arr = arr[:, :, :3]
    if arr.shape[0] < 1 or arr.shape[1] < 1:
        raise DngError(path, f"empty image ({arr.shape[1]}x{arr.shape[0]})")
    return np.ascontiguousarray(arr)


# ----------------------------------------------------------------------------- Pillow (PNG, JPEG)

def _set_rawmode(im, rawmode: str):
    """Make Pillow's PNG decoder unpack the (single) tile with another raw mode."""
    tile = im.tile[0]
    if hasattr(tile, "_replace"):        # Pillow >= 11: ImageFile._Tile namedtuple
        im.tile = [tile._replace(args=rawmode)]
    else:
        im.tile = [(tile[0], tile[1], tile[2], rawmode)]


def _png_16bit(path: Path, rawmode: str) -> np.ndarray:
    """The uint16 samples of a 16-bit colour PNG (RGB, RGBA or grey+alpha), see module doc."""
    from PIL import Image

    with Image.open(path) as im:                     # high bytes: Pillow's default unpacking
        if rawmode == "LA;16B":                      # grey+alpha: 4 bytes/pixel = 8-bit RGBA
            _set_rawmode(im, "RGBA")
            b = np.asarray(im)
            return (b[:, :, 0].astype(np.uint16) << 8) | b[:, :, 1]
        hi = np.asarray(im)
    with Image.open(path) as im:                     # low bytes: little-endian unpacker
        _set_rawmode(im, rawmode.replace(";16B", ";16L"))
        lo = np.asarray(im)
    if hi.shape != lo.shape:
        raise DngError(path, "inconsistent 16-bit PNG decode")
    return (hi.astype(np.uint16) << 8) | lo


def _allow_in_pillow(max_pixels) -> None:
    """Our budget is checked before Pillow opens a file; Pillow's own lower limit (and its
    'decompression bomb' message) must not stand in front of a budget the user raised."""
    from PIL import Image

    if Image.MAX_IMAGE_PIXELS is not None and (max_pixels is None or max_pixels > Image.MAX_IMAGE_PIXELS):
        Image.MAX_IMAGE_PIXELS = max_pixels


def _read_pillow(path: Path, max_pixels=DEFAULT_MAX_PIXELS) -> tuple:
    """(array uint8 or uint16 (H, W, 3), bits) via Pillow."""
    from PIL import Image

    _allow_in_pillow(max_pixels)
    with Image.open(path) as im:
        check_pixel_budget(path, im.size[0], im.size[1], max_pixels)
        rawmode = im.tile[0][3] if im.tile and len(im.tile[0]) > 3 else None
        rawmode = rawmode if isinstance(rawmode, str) else None
        fmt, mode = im.format, im.mode
        if fmt == "PNG" and rawmode in ("RGB;16B", "RGBA;16B", "LA;16B"):
            im.close()
            return _to_rgb(_png_16bit(path, rawmode), path), 16
        if mode in ("I;16", "I;16B", "I;16L", "I;16N"):
            return _to_rgb(np.asarray(im).astype(np.uint16), path), 16
        if mode == "I":                       # 16-bit grey from older Pillow versions
            arr = np.asarray(im)
            if arr.size and (arr.min() < 0 or arr.max() > 65535):
                raise DngError(path, "32-bit integer image not supported (8 or 16 bits only)")
            return _to_rgb(arr.astype(np.uint16), path), 16
        if mode == "F":
            raise DngError(path, "floating-point image not supported here (use EXR for linear data)")
        if mode in ("L", "LA", "La", "RGB", "RGBA", "RGBa", "RGBX"):
            return _to_rgb(np.asarray(im), path), 8
        if mode in ("P", "PA", "1"):
            return _to_rgb(np.asarray(im.convert("RGBA")), path), 8
        return _to_rgb(np.asarray(im.convert("RGB")), path), 8     # CMYK, YCbCr, LAB, HSV


# ----------------------------------------------------------------------------- libspng (8-bit PNG)

_SPNG_COLOUR_TYPES = (0, 2, 3, 6)    # grey (1-8 bits), RGB8, palette, RGBA8: libspng's G8/RGB8/RGBA8 outputs
PLAUSIBLE_PNG_RATIO = 64             # filtered bytes per compressed byte decoded without counting them first


def _read_png_fast(path: Path, max_pixels) -> Optional[tuple]:
    """(uint8 (H, W, 3), 8) through libspng, or None for the Pillow route: 16-bit or grey+alpha
    PNGs, and any file libspng refuses (Pillow's route then names the problem).

    A header claiming more than `PLAUSIBLE_PNG_RATIO` times the compressed data present goes the
    counting route first (`check_png_complete`): memory stays within that ratio of the file's real
    data. libspng itself refuses data that ends early ('IDAT stream too short')."""
    data = path.read_bytes()
    width, height, depth, colour, claimed, present = png_claim(path, data)
    check_pixel_budget(path, width, height, max_pixels)
    if colour not in _SPNG_COLOUR_TYPES or (colour in (2, 6) and depth != 8) or (colour == 0 and depth > 8):
        return None
    if claimed > PLAUSIBLE_PNG_RATIO * max(present, 1):
        check_png_complete(path, max_pixels)
    import imagecodecs

    try:
        array = imagecodecs.spng_decode(data)
    except Exception:  # noqa: BLE001 - refused here, decoded or named by the Pillow route
        return None
    return _to_rgb(array, path), 8


# ----------------------------------------------------------------------------- tifffile (TIFF)

def _read_tiff(path: Path, max_pixels) -> tuple:
    """(array uint8 or uint16 (H, W, 3), bits) via tifffile; first page only."""
    import tifffile

    with tifffile.TiffFile(str(path)) as tif:
        if not tif.pages:
            raise DngError(path, "TIFF has no images")
        page = tif.pages.first
        check_pixel_budget(path, int(page.imagewidth), int(page.imagelength), max_pixels)
        end = max((int(o) + int(n) for o, n in zip(page.dataoffsets, page.databytecounts)), default=0)
        if end > path.stat().st_size or (page.dataoffsets and not any(page.databytecounts)):
            raise DngError(path, f"truncated: its image data ends at byte {end}, the file has {path.stat().st_size}")
        bits = int(np.max(np.atleast_1d(page.bitspersample)))
        photometric = int(page.photometric)
        if page.dtype is None or page.dtype.kind == "f":
            raise DngError(path, "floating-point TIFF not supported (use EXR for linear data)")
        if bits not in (8, 16) or page.dtype.kind != "u":
            raise DngError(path, f"{bits}-bit {page.dtype} TIFF not supported (8- or 16-bit unsigned only)")
        if photometric not in (0, 1, 2, 3):   # MINISWHITE, MINISBLACK, RGB, PALETTE
            raise DngError(path, f"TIFF PhotometricInterpretation {photometric} not supported")
        colormap = page.colormap if photometric == 3 else None
        separate = int(page.planarconfig) == 2
        try:
            arr = page.asarray()
        except Exception as exc:  # e.g. LZW/PackBits/JPEG without the optional imagecodecs package
            arr = None
            failure = exc
    if arr is None:
        # Pillow decodes those too, but keeps only 8 bits of 16-bit colour: use it where lossless
        if bits == 16 and photometric == 2:
            raise DngError(path, f"cannot decode this 16-bit colour TIFF ({_short(failure)})")
        return _read_pillow(path, max_pixels)
    if separate and arr.ndim == 3:
        arr = np.moveaxis(arr, 0, -1)
    if arr.ndim == 3 and photometric in (0, 1):
        arr = arr[:, :, 0]                  # grey + extra samples
    if photometric == 0:
        arr = (2**bits - 1) - arr
    if photometric == 3:
        if colormap is None:
            raise DngError(path, "palette TIFF without a ColorMap")
        colormap = np.asarray(colormap, dtype=np.uint16)
        arr = np.moveaxis(colormap[:, arr], 0, -1)
        if np.all(colormap % 257 == 0):
            return _to_rgb((arr // 257).astype(np.uint8), path), 8
        return _to_rgb(arr, path), 16
    return _to_rgb(arr, path), bits


# ----------------------------------------------------------------------------- OpenEXR

def _exr_size(path: Path) -> tuple:
    """(width, height) of an EXR's dataWindow, read from its header only."""
    import OpenEXR

    with OpenEXR.File(str(path), header_only=True) as exr:
        (x0, y0), (x1, y1) = (np.asarray(corner).tolist() for corner in exr.header()["dataWindow"])
    return int(x1) - int(x0) + 1, int(y1) - int(y0) + 1


def _read_exr(path: Path, max_pixels=DEFAULT_MAX_PIXELS) -> np.ndarray:
    import OpenEXR

    from g2r_jax.io.native_stderr import captured_native_stderr

    try:
        with captured_native_stderr(lambda line: "(EXR_ERR" in line or "OpenEXR" in line):
            width, height = _exr_size(path)
    except Exception as exc:
        raise DngError(path, f"cannot read EXR header, damaged or truncated ({_short(exc)})") from exc
    check_pixel_budget(path, width, height, max_pixels)
    try:
        with captured_native_stderr(lambda line: "(EXR_ERR" in line or "OpenEXR" in line), \
                OpenEXR.File(str(path), separate_channels=True) as exr:
            channels = exr.channels()
            names = list(channels)
            wanted = None
            if all(c in channels for c in "RGB"):
                wanted = ["R", "G", "B"]
            else:
                layers = {n.rsplit(".", 1)[0] for n in names if "." in n}
                layers = [l for l in layers if all(f"{l}.{c}" in channels for c in "RGB")]
                if len(layers) == 1:
                    wanted = [f"{layers[0]}.{c}" for c in "RGB"]
                elif "Y" in channels:
                    wanted = ["Y", "Y", "Y"]
            if wanted is None:
                raise DngError(path, f"EXR has no R, G, B channels (has {', '.join(sorted(names)) or 'none'})")
            planes = []
            for name in wanted:
                ch = channels[name]
                if getattr(ch, "xSampling", 1) != 1 or getattr(ch, "ySampling", 1) != 1:
                    raise DngError(path, f"EXR channel {name} is subsampled; not supported")
                pix = np.asarray(ch.pixels)
                if pix.dtype.kind != "f":
                    raise DngError(path, f"EXR channel {name} is {pix.dtype}, not half or float")
                planes.append(pix.astype(np.float32))
    except DngError:
        raise
    except Exception as exc:
        raise DngError(path, f"cannot read EXR, damaged or truncated ({_short(exc)})") from exc
    image = np.stack(planes, axis=-1)
    if image.ndim != 3 or image.shape[0] < 1 or image.shape[1] < 1:
        raise DngError(path, f"unexpected EXR image shape {image.shape}")
    bad = int(np.count_nonzero(~np.isfinite(image)))
    if bad:
        raise DngError(path, f"contains {bad} NaN/Inf values")
    negative = int(np.count_nonzero(image < 0))
    if negative:
        raise DngError(path, f"contains {negative} negative values (minimum {float(image.min()):.4g}); "
                             "linear scene radiance must be >= 0: clamp or fix the render")
    return np.ascontiguousarray(image)


# ----------------------------------------------------------------------------- public API

def _signature(path: Path) -> bytes:
    with open(path, "rb") as handle:
        return handle.read(8)


def _read_integer(path: Path, ext: str, max_pixels=DEFAULT_MAX_PIXELS) -> tuple:
    """(uint8/uint16 (H, W, 3), bits) for PNG, JPEG or TIFF; DngError on any failure."""
    try:
        if ext in (".tif", ".tiff"):
            return _read_tiff(path, max_pixels)
        if _signature(path) == PNG_SIGNATURE:
            decoded = _read_png_fast(path, max_pixels)
            if decoded is not None:
                return decoded
            check_png_complete(path, max_pixels)
        elif ext in (".jpg", ".jpeg"):
            check_jpeg_complete(path, max_pixels)
        return _read_pillow(path, max_pixels)
    except DngError:
        raise
    except Exception as exc:
        raise DngError(path, f"cannot decode image, damaged, truncated or not a {ext[1:].upper()} "
                             f"({type(exc).__name__}: {_short(exc)})") from exc


def read_image(path: PathLike, max_pixels: Optional[int] = DEFAULT_MAX_PIXELS) -> tuple:
    """Read one image: (float32 (H, W, 3) values, encoding 'srgb' or 'linear').

    An image larger than `max_pixels` (None: no budget) or whose data holds fewer rows than its
    header claims raises `DngError` before it is decoded.

    PNG, JPEG, TIFF (8 or 16 bits): code values divided by 255 or 65535, encoding 'srgb'.
    EXR (half or float R, G, B; a single layer's X.R, X.G, X.B or a Y channel also work):
    values as stored, encoding 'linear'; NaN/Inf or negative values raise `DngError` with
    their count.
    """
    path = Path(path)
    ext = _check_file(path)
    if ext in EXR_EXTENSIONS:
        return _read_exr(path, max_pixels), "linear"
    arr, bits = _read_integer(path, ext, max_pixels)
    scale = np.float32(1.0 / (255.0 if bits == 8 else 65535.0))
    return arr.astype(np.float32) * scale, "srgb"


def read_image_uint8(path: PathLike, max_pixels: Optional[int] = DEFAULT_MAX_PIXELS) -> Optional[np.ndarray]:
    """The (H, W, 3) uint8 code values when the file is an 8-bit PNG/JPEG/TIFF, else None.

    For a look-up-table sRGB decode downstream; 16-bit images and EXR give None.
    """
    path = Path(path)
    ext = _check_file(path)
    if ext in EXR_EXTENSIONS:
        return None
    arr, bits = _read_integer(path, ext, max_pixels)
    return arr if bits == 8 and arr.dtype == np.uint8 else None


def list_inputs(paths: Union[PathLike, Iterable[PathLike]],
                extensions: Iterable[str] = IMAGE_EXTENSIONS) -> list:
    """Expand files and folders into a list of input files.

    A folder contributes its files (not sub-folders, not hidden '.' files) whose extension is
    in `extensions` (case-insensitive), sorted by name; a folder with none raises `DngError`.
    A file is taken as given if its extension is in `extensions`, else `DngError`. A missing path
    raises `DngError`. Duplicates are dropped, first occurrence kept.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    exts = {e.lower() if e.startswith(".") else "." + e.lower() for e in extensions}
    out, seen = [], set()
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted((f for f in p.iterdir()
                            if not f.name.startswith(".") and f.is_file() and f.suffix.lower() in exts),
                           key=lambda f: f.name)
            if not found:
                raise DngError(p, f"folder has no input files ({', '.join(sorted(exts))})")
        elif p.is_file():
            if p.suffix.lower() not in exts:
                raise DngError(p, f"unsupported file type '{p.suffix}' (expected {', '.join(sorted(exts))})")
            found = [p]
        else:
            raise DngError(p, "no such file or folder")
        for f in found:
            key = str(f.resolve())
            if key not in seen:
                seen.add(key)
                out.append(f)
    return out


def read_images(paths: Union[PathLike, Iterable[PathLike]], *, max_pixels: Optional[int] = DEFAULT_MAX_PIXELS,
                min_side: int = 1, problem: Optional[Callable[[str, str], None]] = None) -> list:
    """Every image of `paths` (files or folders, expanded by `list_inputs`) that reads:
    [(path, float32 (H, W, 3) values, encoding)] as `read_image` gives them, in input order.

    A file that does not read (`DngError`), or whose shorter side is under `min_side` pixels, is
    passed to `problem(path, reason)` and left out, so that one bad file does not stop a set;
    without `problem` the first such file raises `DngError`. A path that is missing, or a folder
    without images, raises `DngError` as in `list_inputs`.
    """
    out = []
    for path in list_inputs(paths):
        try:
            values, encoding = read_image(path, max_pixels)
            if min(values.shape[:2]) < min_side:
                raise DngError(path, f"{values.shape[0]} x {values.shape[1]} is smaller than {min_side} pixels")
        except DngError as error:
            if problem is None:
                raise
            problem(str(path), error.problem)
            continue
        out.append((path, values, encoding))
    return out
