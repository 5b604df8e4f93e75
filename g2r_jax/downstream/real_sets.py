"""Real test sets: the NUS 8-camera thumbnails, or a folder of a user's DNGs.

A user's DNG gives one thumbnail (`thumbnails.camera_rgb_thumbnail` of its black-subtracted,
range-scaled CFA tiles) labelled with its AsShotNeutral: the camera's own white balance, not a
measured chart, so the check measures how well a network trained on synthetic RAW agrees with
the camera's AWB on the user's scenes.
"""

from __future__ import annotations

import collections
import dataclasses
from pathlib import Path

import numpy as np

from g2r_jax.downstream import thumbnails as _thumbnails

NUS_LABEL = "measured (the grey patches of a ColorChecker in each scene)"
DNG_LABEL = "AsShotNeutral (the camera's own white balance)"


@dataclasses.dataclass
class RealSet:
    """Real thumbnails of one camera with their illuminants.

    `images` (N, 64, 64, 3) linear camera RGB, saturated pixels 0, maximum 1 (`thumbnails`);
    `illuminants` (N, 3); `label`: where the illuminants come from (a measured chart, or each
    file's AsShotNeutral: the camera's own white balance)."""

    name: str
    images: np.ndarray
    illuminants: np.ndarray
    label: str = "measured"
    files: tuple = ()


def load_nus(path) -> RealSet:
    """One camera of the NUS set as republished (see ../shared/data/PROVENANCE.md): an .npz with
    `images` (N, 64, 64, 3) linear raw RGB and `illuminants` (N, 3)."""
    path = Path(path)
    try:
        with np.load(path) as data:
            images = np.asarray(data["images"], np.float32)
            illuminants = np.asarray(data["illuminants"], np.float64)
            names = tuple(str(n) for n in data["names"]) if "names" in data else ()
    except (OSError, KeyError, ValueError) as error:
        raise ValueError(f"{path}: not a real set (.npz with images and illuminants): {error}") from None
    if images.ndim != 4 or images.shape[1:] != (64, 64, 3) or illuminants.shape != (len(images), 3):
        raise ValueError(f"{path}: images {images.shape} and illuminants {illuminants.shape} are not "
                         "(N, 64, 64, 3) and (N, 3)")
    if not np.all(np.isfinite(illuminants)) or np.any(illuminants <= 0):
        raise ValueError(f"{path}: illuminants must be finite and positive")
    return RealSet(name=path.stem, images=images, illuminants=illuminants / illuminants.sum(1, keepdims=True),
                   label=NUS_LABEL, files=names)


def dng_thumbnail(path):
    """(thumbnail (64, 64, 3), as-shot neutral (3,), DngInfo) of one Bayer DNG; DngError naming
    the file when it cannot be used."""
    from g2r_jax.io.dng_info import DngError
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels, require_colour_tags
    from g2r_jax.profile.fitting import as_shot_neutral

    info = require_colour_tags(read_dng_info(path))
    neutral = as_shot_neutral(info)
    if neutral is None or not np.all(np.isfinite(neutral)) or np.any(neutral <= 0):
        raise DngError(path, "no usable AsShotNeutral (or AsShotWhiteXY): the file has no white-balance label")
    mosaic = read_dng_pixels(path, info)
    rgb = _thumbnails.mosaic_to_camera_rgb(mosaic, info.cfa_pattern, info.black_level, info.white_level)
    try:
        thumb = _thumbnails.camera_rgb_thumbnail(rgb)
    except ValueError as error:
        raise DngError(path, str(error)) from None
    if thumb.max() <= 0:
        raise DngError(path, "every pixel is clipped or black: nothing to estimate a light from")
    return thumb, neutral, info


def load_dng_folder(paths, *, on_file=None) -> tuple[RealSet, list[tuple[str, str]]]:
    """Thumbnails and as-shot neutrals of a camera's DNGs (files or folders of *.dng).

    Files that cannot be used, and files of another camera than the majority's, are skipped
    and returned as (path, reason); the rest is the set. `on_file(path)` is called after each file.
    **Returns:** (RealSet, skipped).
    """
    from g2r_jax.io.dng_info import DngError

    files = []
    for item in paths:
        item = Path(item)
        files.extend(sorted(p for p in item.iterdir() if p.suffix.lower() == ".dng") if item.is_dir() else [item])
    kept, skipped = [], []
    for path in files:
        try:
            thumb, neutral, info = dng_thumbnail(path)
            kept.append((path, thumb, neutral, info.unique_camera_model or f"{info.make} {info.model}".strip()))
        except DngError as error:
            skipped.append((str(path), error.problem))
        except (OSError, ValueError) as error:
            skipped.append((str(path), str(error)))
        if on_file:
            on_file(path)
    if not kept:
        return RealSet(name="", images=np.zeros((0, 64, 64, 3), np.float32), illuminants=np.zeros((0, 3)),
                       label=DNG_LABEL), skipped
    camera = collections.Counter(k[3] for k in kept).most_common(1)[0][0]
    for path, _, _, model in kept:
        if model != camera:
            skipped.append((str(path), f"camera {model!r}, not {camera!r} like the other files"))
    kept = [k for k in kept if k[3] == camera]
    neutrals = np.stack([k[2] for k in kept])
    return RealSet(name=camera, images=np.stack([k[1] for k in kept]),
                   illuminants=neutrals / neutrals.sum(1, keepdims=True), label=DNG_LABEL,
                   files=tuple(str(k[0]) for k in kept)), skipped
