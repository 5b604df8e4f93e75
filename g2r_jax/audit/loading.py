"""Loading measured files and scene images for the audit (the I/O edge of the package)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from g2r_jax.batch.conversion import IMAGE_EXTENSIONS
from g2r_jax.io.dng_info import DngError, DngInfo

DNG_SUFFIXES = (".dng",)


def measured_paths(folder) -> list[Path]:
    """The DNG files of a folder, sorted by name, or one DNG file given by its path; DngError when
    there are none."""
    folder = Path(folder)
    if folder.is_file() and folder.suffix.lower() in DNG_SUFFIXES:
        return [folder]
    if not folder.is_dir():
        raise DngError(folder, "neither a folder nor a .dng file")
    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in DNG_SUFFIXES)
    if not paths:
        raise DngError(folder, "no .dng files in this folder")
    return paths


def load_measured(items, *, on_error=None) -> list[tuple[np.ndarray, DngInfo]]:
    """(mosaic, DngInfo) for each item: a path to a DNG, or an in-memory (mosaic, DngInfo) pair.

    Raises DngError naming the file for anything unreadable, non-Bayer, undecodable (e.g. VC-5 or
    JPEG XL raw data), or a too-small mosaic. With `on_error`, each such file is reported as one
    line to `on_error(line)` and skipped, and so are files whose size differs from the most common
    one; DngError then only when no file is left.
    """
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels, require_bayer_cfa

    out, refused = [], []
    for item in items:
        try:
            if isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[1], DngInfo):
                mosaic, info = np.asarray(item[0]), item[1]
            else:
                info = require_bayer_cfa(read_dng_info(item))
                mosaic = read_dng_pixels(item, info)
            if mosaic.ndim != 2 or mosaic.shape[0] < 16 or mosaic.shape[1] < 16:
                raise DngError(info.path, f"mosaic of shape {mosaic.shape} is too small to audit")
        except DngError as error:
            if on_error is None:
                raise
            refused.append(error)
            continue
        if mosaic.shape[0] % 2 or mosaic.shape[1] % 2:
            mosaic = mosaic[: mosaic.shape[0] // 2 * 2, : mosaic.shape[1] // 2 * 2]
        out.append((mosaic, info))
    if on_error is not None:
        if not out and len(refused) == 1:
            raise refused[0]
        for error in refused:
            on_error(str(error))
        shapes = [m.shape for m, _ in out]
        if len(set(shapes)) > 1:
            common = max(set(shapes), key=shapes.count)
            for mosaic, info in out:
                if mosaic.shape != common:
                    on_error(f"{info.path}: mosaic {mosaic.shape[1]}x{mosaic.shape[0]} differs from the "
                             f"{shapes.count(common)} file(s) of {common[1]}x{common[0]}; audit one size at a time")
            out = [(m, i) for m, i in out if m.shape == common]
        if not out:
            first = items[0] if items else "."
            folder = Path(str(first[1].path if isinstance(first, (tuple, list)) else first)).parent
            raise DngError(folder, f"no usable measured DNG files ({len(refused)} refused)")
    return out


def check_measured(items, *, on_error=None) -> list:
    """Read the tags (not the pixels) of every DNG path among `items`, before any work is done:
    DngError naming the first file that cannot be audited, or with `on_error`, one line per such
    file to `on_error(line)` and the usable items returned."""
    from g2r_jax.io.dng_read import read_dng_info, require_bayer_cfa

    usable, refused = [], []
    for item in items:
        try:
            if not (isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[1], DngInfo)):
                require_bayer_cfa(read_dng_info(item))
            usable.append(item)
        except DngError as error:
            if on_error is None:
                raise
            refused.append(error)
    if not usable and len(refused) == 1:
        raise refused[0]
    for error in refused:
        on_error(str(error))
    if not usable:
        raise DngError(folder_of(items), f"no usable measured DNG files ({len(items)} refused)")
    return usable


def folder_of(items) -> Path:
    """The folder of the first item (a path or a (mosaic, DngInfo) pair), for messages."""
    first = items[0] if items else "."
    return Path(str(first[1].path if isinstance(first, (tuple, list)) else first)).parent


def load_scenes(folder, n: int, height: int, width: int, *, with_names: bool = False):
    """(n, H, W, 3) sRGB scenes from the images of a folder (cycled if fewer than n), each
    resized to the measured files' size: uint8 codes when every image is 8-bit sRGB of that size
    already (exactly what `g2r-convert` reads), else floats in [0, 1]. With `with_names`, also
    the file name of each scene (the key of its simulation, `convert.file_key`)."""
    import jax

    from g2r_jax.colour.conversions import linear_to_srgb
    from g2r_jax.io.images import read_image

    folder = Path(folder)
    if not folder.is_dir():
        raise DngError(folder, "scene folder not found")
    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_EXTENSIONS)
    if not paths:
        raise DngError(folder, f"no scene images ({', '.join(IMAGE_EXTENSIONS)}) in this folder")
    from g2r_jax.io.images import read_image_uint8

    codes = [read_image_uint8(path) for path in paths[:n]]
    if all(c is not None and c.shape == (height, width, 3) for c in codes):
        scenes = np.stack([codes[i % len(codes)] for i in range(n)])
    else:
        scenes = []
        for i in range(n):
            # the project's reader: 8/16-bit sRGB or linear EXR, with its checks and error messages
            image, encoding = read_image(paths[i % len(paths)])
            if encoding == "linear":
                image = np.asarray(linear_to_srgb(np.clip(image, 0.0, 1.0)))
            scenes.append(np.asarray(jax.image.resize(image, (height, width, 3), "linear"), np.float32))
        scenes = np.stack(scenes)
    names = [paths[i % len(paths)].name for i in range(n)]
    return (scenes, names) if with_names else scenes
