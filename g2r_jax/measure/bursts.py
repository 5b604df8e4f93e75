"""Bursts: several frames of one static scene, told from unrelated files (issue 29, issue 35).
What each frame's noise is, over time, is `g2r_jax.measure.photon_transfer`'s.

- `is_static_burst(mosaics)` (profile fitting: is this folder a burst?): at least
  `MIN_FRAMES` frames of one shape, each of which minus the frames' median has no structure (its
  8 x 8 block means spread no more than `STRUCTURE_RATIO` x its pixel sd / 8, as pure noise,
  `planes.block_spread`), so the scene did not move and the exposure did not change.
- `find_bursts(files)` (the audit: which of many files form bursts?): groups of at least
  `MIN_FRAMES` files of one size and ISO whose thumbnails agree up to a global gain
  (correlation above `MIN_CORRELATION`); dark frames are never part of a burst.
- `scene_outliers(planes)` (the downstream denoising test: which frames of a declared burst are
  not the same static scene?): a frame whose mean level against the others' is off by more than
  `MAX_EXPOSURE_CHANGE`, or whose mean squared difference from the others' mean exceeds
  `MAX_RESIDUAL_RATIO` times the median frame's (which is the noise alone: (1 + 1/(n-1)) times
  its variance).
"""

from __future__ import annotations

import numpy as np

from g2r_jax.measure.planes import BLOCK, SITES, block_spread
from g2r_jax.measure.robust import iqr_sd

MIN_FRAMES = 4
STRUCTURE_RATIO = 3.0
MIN_CORRELATION = 0.995
MAX_RESIDUAL_RATIO = 2.0    # a frame's mean squared difference from the others' mean over the median frame's
MAX_EXPOSURE_CHANGE = 0.05  # a frame whose gain against the others is off by more than 5 %


def is_static_burst(mosaics) -> bool:
    """True for at least MIN_FRAMES frames of one shape and one static scene (module docstring)."""
    if len(mosaics) < MIN_FRAMES or len({np.shape(m) for m in mosaics}) != 1 or min(np.shape(mosaics[0])) < 32:
        return False
    for dy, dx in SITES:
        stack = np.stack([np.asarray(m)[dy::2, dx::2] for m in mosaics]).astype(np.float64)
        median = np.median(stack, axis=0)
        for frame in stack:
            d = frame - median
            sd = iqr_sd(d)
            if not sd > 0:
                sd = d.std()
            if sd <= 0 or block_spread(d) > STRUCTURE_RATIO * sd / BLOCK:
                return False
    return True


def gain_free_correlation(a, b) -> float:
    """Pearson correlation of the finite pairs of `a` and `b` (0 with fewer than 16 or no spread)."""
    a, b = np.asarray(a, np.float64).ravel(), np.asarray(b, np.float64).ravel()
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 16:
        return 0.0
    a, b = a[ok] - a[ok].mean(), b[ok] - b[ok].mean()
    norm = np.sqrt((a * a).sum() * (b * b).sum())
    return float((a * b).sum() / norm) if norm > 0 else 0.0


def find_bursts(files) -> list[list[int]]:
    """Index groups of `files` (dicts with "shape", "iso", "thumbnail" and optionally "dark_frame",
    e.g. the audit's `stats.file_statistics`) that are bursts of one scene."""
    groups: list[list[int]] = []
    for i, f in enumerate(files):
        if f.get("dark_frame") or not np.all(np.isfinite(f.get("thumbnail", np.nan))):
            continue
        for group in groups:
            first = files[group[0]]
            same = (first["shape"] == f["shape"] and abs(first["iso"] - f["iso"]) <= 0.02 * max(first["iso"], 1.0)
                    and gain_free_correlation(first["thumbnail"], f["thumbnail"]) >= MIN_CORRELATION)
            if same:
                group.append(i)
                break
        else:
            groups.append([i])
    return [g for g in groups if len(g) >= MIN_FRAMES]


def scene_outliers(planes: np.ndarray) -> dict[int, str]:
    """{frame index: reason} for the frames of (n, ...) `planes` that are not the same static
    scene as the others (module docstring)."""
    n = planes.shape[0]
    total = planes.sum(0, dtype=np.float64)
    residual, gains = np.empty(n), np.empty(n)
    for k in range(n):
        others = (total - planes[k]) / (n - 1)
        gains[k] = float(planes[k].sum(dtype=np.float64) / max(float(others.sum()), 1e-30))
        residual[k] = float(np.mean((planes[k] - others) ** 2))
    typical = float(np.median(residual))
    out = {}
    for k in range(n):
        if residual[k] > MAX_RESIDUAL_RATIO * typical:
            out[k] = (f"it differs from the other frames' mean {residual[k] / typical:.1f} times more than the "
                      f"median frame does: not the same static scene (something moved, or the light changed)")
        elif abs(gains[k] - 1.0) > MAX_EXPOSURE_CHANGE:
            out[k] = (f"its mean level differs from the other frames' by {100 * (gains[k] - 1):+.1f} % "
                      f"(more than {100 * MAX_EXPOSURE_CHANGE:.0f} %): not the same exposure of a static scene")
    return out
