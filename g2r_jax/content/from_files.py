"""The content model of a folder of the camera's DNGs: each file's mosaic binned to a small
camera-RGB image (greens of a CFA tile averaged, black subtracted, scaled by the range; 64 x 64
area average, clipped blocks zeroed, as the NUS thumbnails of Cheng, Prasad and Brown, JOSA A
2014), white-balanced by its as-shot neutral, its statistics, and the fit (`fitting`): the 'cast'
family (what g2r-fit-profile stores) through the camera's colour model at the files' median
neutral; the others against the reference CG set (no CG images at hand when a profile is fitted);
and the thumbnails' texture (`texture`), which the pairs of a neural ISP carry.
"""

from __future__ import annotations

from typing import Callable, Optional

import numpy as np

from g2r_jax.content.fitting import fit_content_model
from g2r_jax.content.model import ContentModel
from g2r_jax.content.real_images import srgb_to_camera_matrices, white_balanced_camera_rgb
from g2r_jax.content.scene_statistics import CLIPPED, SIZE, _area_average, statistics


def mosaic_thumbnail(mosaic, cfa_pattern, black_level, white_level, *, size: int = SIZE) -> np.ndarray:
    """(H, W) mosaic in DN -> (size, size, 3) camera RGB in [0, 1] of the range, blocks holding a
    clipped tile zeroed. ValueError when the mosaic is smaller than 2 size x 2 size."""
    mosaic = np.asarray(mosaic, np.float32)
    h, w = mosaic.shape[0] // 2 * 2, mosaic.shape[1] // 2 * 2
    if h < 2 * size or w < 2 * size:
        raise ValueError(f"a mosaic of {mosaic.shape[0]} x {mosaic.shape[1]} is smaller than {2 * size} x {2 * size}")
    black = np.resize(np.asarray(black_level, np.float32), 4)
    sites = [(mosaic[i:h:2, j:w:2] - black[2 * i + j]) / (float(white_level) - black[2 * i + j])
             for i in range(2) for j in range(2)]
    cfa = np.asarray(cfa_pattern).reshape(4)
    rgb = np.clip(np.stack([np.mean([sites[k] for k in range(4) if cfa[k] == c], axis=0) for c in range(3)], -1), 0, 1)
    clipped = _area_average((rgb >= CLIPPED).any(-1, keepdims=True)[None].astype(np.float32), size)[0, ..., 0] > 0
    return np.where(clipped[..., None], 0.0, _area_average(rgb[None], size)[0]).astype(np.float32)


def content_model_from_files(files, read: Callable, *, on_error: Optional[Callable[[object, str], None]] = None,
                             family: str = "cast", colour_model=None) -> tuple[Optional[ContentModel], int]:
    """The content model of a camera's files, fitted to their statistics (no labels).

    **Arguments:** `files`: anything `read` takes; `read(file) -> (mosaic, cfa_pattern,
    black_level, white_level, as_shot_neutral)`; `on_error(file, problem)` is told of each file
    that cannot be used (the others go on); `family`: see `model.FAMILIES`; `colour_model`: the
    camera's (`DngColourModel`), which carries the 'cast' family's target from its white-balanced
    RGB to linear sRGB (None: taken as the identity).
    **Returns:** (model or None when no file could be used, number of files used).
    """
    thumbnails, neutrals = [], []
    for file in files:
        try:
            mosaic, cfa, black, white, neutral = read(file)
            neutral = np.asarray(neutral, np.float64)
            if neutral.shape != (3,) or not np.all(np.isfinite(neutral)) or np.any(neutral <= 0):
                raise ValueError("no usable as-shot neutral")
            thumbnails.append(mosaic_thumbnail(mosaic, cfa, black, white))
            neutrals.append(neutral)
        except (OSError, ValueError) as error:
            if on_error is not None:
                on_error(file, str(error))
    if not thumbnails:
        return None, 0
    real = statistics(white_balanced_camera_rgb(np.stack(thumbnails), np.stack(neutrals)),
                      source=f"{len(thumbnails)} DNG file(s)")
    statistic = "cast_red" if family in ("cast", "scenes") else "chroma_spread"
    if not np.isfinite(real.values[statistic]).any():
        return None, 0
    to_camera = None
    if colour_model is not None:
        stacked = np.stack(neutrals)
        neutral = np.median(stacked / stacked[:, 1:2], axis=0)
        to_camera = srgb_to_camera_matrices(neutral[None], colour_model)[0]
    model = fit_content_model(real, None, family=family, to_camera=to_camera)
    return _with_texture(model, thumbnails), len(thumbnails)


def _with_texture(model: ContentModel, thumbnails) -> ContentModel:
    """`model` carrying the thumbnails' texture (`texture.fit_texture`; as it was when they hold too
    few measured pixels)."""
    import dataclasses

    from g2r_jax.content.texture import fit_texture

    try:
        return dataclasses.replace(model, texture=fit_texture(thumbnails, source=f"{len(thumbnails)} DNG file(s)"))
    except ValueError:
        return model
