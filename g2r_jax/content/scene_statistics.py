"""Content statistics of scene-linear, white-balanced images (a neutral surface is R = G = B).

The statistics the downstream benchmark names as the CG content's gap (see
`docs/pages/validation/downstream.md`), compared in one space and at one resolution (each image
area-averaged to 64 x 64 first, the estimators' thumbnail size). The space is the camera's
white-balanced RGB, where the estimator works: real files divided by their as-shot neutral, CG
images (linear sRGB) through the profile's DNG transform (`real_images`). Linear sRGB works as
well for CG images, but real colours outside the sRGB gamut turn negative there, and the
log-chroma of a clipped channel is meaningless (measured: the NUS scenes' median log-chroma spread
reads 0.46 in clipped sRGB against 0.21 in camera RGB; see the validation page).

Per image, with `peak` its largest channel value and luminance the Y row of linear sRGB
(IEC 61966-2-1 primaries, `colour.conversions.MATRIX_SRGB_TO_XYZ`):
- `chroma_spread`: standard deviation of the log-chroma (log R/G, log B/G; Finlayson and
  Hordley's chromaticity space, as in Barron, "Convolutional Color Constancy", ICCV 2015), root of
  the mean of the two variances, over lit pixels (luminance >= 5 % of the peak, no channel
  clipped), each channel floored at 1e-4 of the peak;
- `brightness`: mean luminance over the peak;
- `dark_share`: share of pixels with luminance below 2 % of the peak;
- `clipped_share`: share of pixels with a channel at >= 98 % of the peak, or zeroed (the real
  thumbnails zero their saturated pixels);
- `contrast`: log2 of the 95th over the 5th percentile of lit luminance;
- `cast_red`, `cast_blue`: the image's grey-world cast, log R/G and log B/G of its mean colour
  over the pixels not clipped (Buchsbaum's grey world, J. Franklin Inst. 1980: 0 for an image
  whose mean is neutral). Real scenes balanced by their light are warm on the median (NUS: about
  +0.05 and -0.08); the CARLA frames are blue (about -0.09 and +0.15) with little spread between
  frames (docs/pages/validation/content_model.md, finding 3).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from g2r_jax.colour.conversions import MATRIX_SRGB_TO_XYZ

NAMES = ("chroma_spread", "brightness", "dark_share", "clipped_share", "contrast", "cast_red", "cast_blue")
SIZE = 64
LIT = 0.05
DARK = 0.02
CLIPPED = 0.98
FLOOR = 1e-4
_EPS = 1e-12
LUMINANCE = np.asarray(MATRIX_SRGB_TO_XYZ[1], np.float64)


def luminance(x):
    """Y of linear sRGB, (..., 3) -> (..., 1), element-wise in any array library (NumPy or JAX:
    it fuses with a compiled program's other pixel stages)."""
    weights = [float(w) for w in LUMINANCE]
    return weights[0] * x[..., 0:1] + weights[1] * x[..., 1:2] + weights[2] * x[..., 2:3]


@dataclasses.dataclass(frozen=True)
class ContentStatistics:
    """Per-image statistics (each an (N,) array, NaN where an image has too few lit pixels) and
    where they came from."""

    values: dict
    source: str = ""

    def median(self, name: str) -> float:
        finite = self.values[name][np.isfinite(self.values[name])]
        if not len(finite):
            raise ValueError(f"{self.source or 'content statistics'}: no image has a finite {name}")
        return float(np.median(finite))

    def medians(self) -> dict:
        return {name: self.median(name) for name in NAMES}

    def __len__(self) -> int:
        return len(self.values[NAMES[0]])


def _area_average(images: np.ndarray, size: int) -> np.ndarray:
    """(N, h, w, 3) -> (N, size, size, 3), block edges rounded to whole pixels."""
    n, h, w, _ = images.shape
    if h == size and w == size:
        return images
    rows = np.linspace(0, h, size + 1).round().astype(int)
    cols = np.linspace(0, w, size + 1).round().astype(int)
    sums = np.add.reduceat(np.add.reduceat(images, rows[:-1], axis=1), cols[:-1], axis=2)
    return sums / np.outer(np.diff(rows), np.diff(cols))[None, :, :, None]


def _masked_percentile(values: np.ndarray, mask: np.ndarray, q: float) -> np.ndarray:
    return np.nanpercentile(np.where(mask, values, np.nan), q, axis=1)


def statistics(images, *, source: str = "") -> ContentStatistics:
    """Content statistics of linear sRGB images, white-balanced (a neutral surface is R = G = B).

    **Arguments:** `images`: (N, H, W, 3) or a list of (H, W, 3) arrays, linear, >= 0 (negative
    values are clipped to 0), H and W >= 64; `source`: named in errors.
    **Returns:** a `ContentStatistics` (keys `NAMES`).
    """
    if isinstance(images, (list, tuple)):
        images = np.stack([_area_average(np.asarray(i, np.float64)[None], SIZE)[0] for i in images]) if images else np.zeros((0, SIZE, SIZE, 3))
    images = np.asarray(images, np.float64)
    if images.ndim != 4 or images.shape[-1] != 3 or min(images.shape[1:3]) < SIZE:
        raise ValueError(f"{source or 'images'}: expected (N, H, W, 3) with H, W >= {SIZE}, got {images.shape}")
    if not np.all(np.isfinite(images)):
        raise ValueError(f"{source or 'images'}: non-finite pixel values")
    pixels = np.maximum(_area_average(images, SIZE), 0.0).reshape(len(images), -1, 3)
    peak = np.maximum(pixels.max(axis=(1, 2)), _EPS)[:, None]
    luminance = pixels @ LUMINANCE / peak
    clipped = np.any(pixels >= CLIPPED * peak[..., None], axis=-1) | np.all(pixels <= 0, axis=-1)
    lit = (luminance >= LIT) & ~clipped
    floor = FLOOR * peak[..., None]
    chroma = np.log(np.maximum(pixels[..., [0, 2]], floor) / np.maximum(pixels[..., 1:2], floor))
    count = lit.sum(1)
    mean = np.einsum("np,npc->nc", lit, chroma) / np.maximum(count, 1)[:, None]
    variance = np.einsum("np,npc->nc", lit, (chroma - mean[:, None]) ** 2) / np.maximum(count - 1, 1)[:, None]
    enough = count >= 8
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # an image without lit pixels gives NaN
        low, high = _masked_percentile(luminance, lit, 5), _masked_percentile(luminance, lit, 95)
    kept = ~clipped
    mean_colour = np.einsum("np,npc->nc", kept, pixels) / np.maximum(kept.sum(1), 1)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        cast = np.log(mean_colour[:, [0, 2]] / mean_colour[:, 1:2])
    cast = np.where(np.isfinite(cast) & (kept.sum(1) > 0)[:, None], cast, np.nan)
    values = {
        "chroma_spread": np.where(enough, np.sqrt(variance.mean(1)), np.nan),
        "brightness": luminance.mean(1),
        "dark_share": (luminance < DARK).mean(1),
        "clipped_share": clipped.mean(1),
        "contrast": np.where(enough, np.log2(np.maximum(high, _EPS) / np.maximum(low, _EPS)), np.nan),
        "cast_red": cast[:, 0],
        "cast_blue": cast[:, 1],
    }
    return ContentStatistics(values=values, source=source)


def concatenate(parts, source: str = "") -> ContentStatistics:
    """One `ContentStatistics` from several (e.g. the batches of a folder)."""
    return ContentStatistics(values={k: np.concatenate([p.values[k] for p in parts]) for k in NAMES}, source=source)
