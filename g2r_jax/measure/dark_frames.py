"""Dark frames (captures with the lens capped) recognised from their pixels, and their per-site
statistics; profile fitting (read noise, black level) and the audit (black-level evidence) both
take them from here (issue 29, issue 35).

- `is_dark_frame(mosaic, black, white)`: no light. Per CFA site its median lies within
  `DARK_LEVEL_MAX` of the range of the tag, at most `CLIPPED_FRACTION` of its pixels sit at raw 0
  (a clipped frame's moments are biased) and at most `OUTLIER_FRACTION` lie beyond `OUTLIER_SIGMAS`
  (hot pixels are rare; a light in a night scene is not), and its 8 x 8 block means (outliers set
  to the centre) spread no more than pixel noise allows (`planes.block_spread`): robust sd at most
  `STRUCTURE_RATIO` x sd / 8 and the 0.1-99.9 percentile range at most 10 x that, sd from
  differences of horizontal neighbours of the site (which a scene's structure does not raise).
  Row or column banding passes (a block mean of 8 rows carries a row offset's variance / 8,
  which the ratio allows).
- `dark_frame_statistics(mosaic)`: per site the mean and the variance about the frame's own mean,
  hot pixels left out (iterated clipping at `OUTLIER_SIGMAS`, whose truncation of Gaussian values
  lowers the variance by under 1e-7), and the share of that variance in row and column means
  (banding), all in DN.
- `find_dark_frames(infos)`: the dark frames among decoded DNG files.

The read noise a profile takes from these statistics (rounding undone) is
`g2r_jax.sensor.dark_frames.read_from_dark_frames`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from g2r_jax.measure.planes import BLOCK, block_means, site_planes
from g2r_jax.measure.robust import iqr_sd

DARK_LEVEL_MAX = 0.05      # median within this fraction of the range of the tag
STRUCTURE_RATIO = 3.0      # block-mean spread at most this many times what pixel noise gives
CLIPPED_FRACTION = 1e-3    # more pixels than this at raw 0: the frame's moments are biased
OUTLIER_SIGMAS = 6.0       # hot pixels: beyond this many sd of the site's centre
OUTLIER_FRACTION = 2e-3    # more outliers than this: scene content, not hot pixels


def clipped_moments(values, sigmas: float = OUTLIER_SIGMAS, iterations: int = 20):
    """(mean, variance, inlier mask) of `values` with outliers left out: values beyond `sigmas`
    sd of the mean of the kept ones, iterated from the median and the interquartile spread
    (`iqr_sd`; or the sd where integer data of under 1 DN make the quartiles coincide)."""
    v = np.asarray(values, np.float64).ravel()
    centre = np.median(v)
    sd = iqr_sd(v)
    if not sd > 0:
        sd = np.sqrt(np.mean((v - centre) ** 2 * (np.abs(v - centre) <= 3)))
    keep = np.ones(v.shape, bool)
    for _ in range(iterations):
        new_keep = np.abs(v - centre) <= sigmas * max(sd, 0.5)
        if not new_keep.any():
            break
        centre, sd = v[new_keep].mean(), v[new_keep].std()
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    return float(centre), float(sd**2), keep.reshape(np.shape(values))


def _site_is_dark(plane, black: float, span: float) -> bool:
    if abs(np.median(plane) - black) > DARK_LEVEL_MAX * span:
        return False
    centre, variance, keep = clipped_moments(plane)
    if variance <= 0 or np.mean(~keep) > OUTLIER_FRACTION:
        return False
    h, w = plane.shape[0] // BLOCK * BLOCK, plane.shape[1] // BLOCK * BLOCK
    if h == 0 or w == 0:
        return False
    clean = np.where(keep, plane, centre)[:h, :w]
    blocks = block_means(clean).ravel()
    # pixel noise from neighbour differences: a scene's structure (and row banding) cancels there
    _, difference_variance, _ = clipped_moments(np.diff(clean, axis=1))
    allowed = STRUCTURE_RATIO * np.sqrt(difference_variance / 2) / BLOCK
    return not (iqr_sd(blocks) > allowed or np.ptp(np.percentile(blocks, [0.1, 99.9])) > 10 * allowed)


def is_dark_frame(mosaic, black_level, white_level) -> bool:
    """True for a frame without light (see the module docstring). `black_level`: the tag's (4,)
    (or one value) DN; `white_level`: DN, one value or (4,)."""
    m = np.asarray(mosaic)
    if m.ndim != 2 or min(m.shape) < 2 * BLOCK:
        return False
    if np.mean(m == 0) > CLIPPED_FRACTION:
        return False
    black = np.resize(np.asarray(black_level, np.float64).reshape(-1), 4)
    span = np.resize(np.asarray(white_level, np.float64).reshape(-1), 4) - black
    step = max(1, int(np.sqrt(m.size / 4 / 250_000)))     # large files: a strided subset of rows will do
    return all(_site_is_dark(plane[::step], black[p], span[p]) for p, plane in enumerate(site_planes(m)))


@dataclasses.dataclass(frozen=True)
class DarkFrameStatistics:
    """One dark frame, per CFA site (4,), DN: `mean`, `variance` about the mean (hot pixels left
    out), `count` pixels used, `hot` pixels left out, `banding` variance of the row and column
    means beyond what pixel noise gives them (a part of `variance`)."""

    mean: np.ndarray
    variance: np.ndarray
    count: np.ndarray
    hot: np.ndarray
    banding: np.ndarray


def dark_frame_statistics(mosaic) -> DarkFrameStatistics:
    """`DarkFrameStatistics` of one dark frame's integer mosaic."""
    out = {k: np.zeros(4) for k in ("mean", "variance", "count", "hot", "banding")}
    for p, plane in enumerate(site_planes(mosaic)):
        centre, variance, keep = clipped_moments(plane)
        out["mean"][p], out["variance"][p] = centre, variance
        out["count"][p], out["hot"][p] = keep.sum(), (~keep).sum()
        clean = np.where(keep, plane, centre) - centre
        rows, cols = clean.mean(axis=1), clean.mean(axis=0)
        out["banding"][p] = (max(rows.var() - variance / plane.shape[1], 0.0)
                             + max(cols.var() - variance / plane.shape[0], 0.0))
    return DarkFrameStatistics(**out)


def find_dark_frames(infos) -> tuple[list, list]:
    """(the files that are not dark frames, [(info, DarkFrameStatistics)] of those that are),
    each file's pixels decoded by LibRaw (`g2r_jax.io.dng_read.read_dng_pixels`) with its own tags'
    levels. A file whose pixels do not decode is not a dark frame (its problem is reported where
    its pixels are needed: the noise measurement)."""
    from g2r_jax.io.dng_read import read_dng_pixels

    scenes, dark = [], []
    for info in infos:
        try:
            mosaic = read_dng_pixels(info.path, info)
        except Exception:  # noqa: BLE001 - DngError and anything LibRaw raises: not a dark frame
            scenes.append(info)
            continue
        if is_dark_frame(mosaic, info.black_level, info.white_level):
            dark.append((info, dark_frame_statistics(mosaic)))
        else:
            scenes.append(info)
    return scenes, dark
