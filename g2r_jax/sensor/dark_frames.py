"""Dark frames in a folder of raws: recognised from their pixels, and the read noise and the black
level per CFA site measured from them (issue 29).

A dark frame (a capture with the lens capped) holds, per CFA site, the black level, the read noise
(temporal noise, the dark signal's fixed pattern, row/column banding) and the rounding to DN:
what a simulated black frame must hold. Measured directly there, the read term needs no
extrapolation of a noise level function to zero signal, whose intercept the scene's texture and
the level bins' spread bias (`g2r_jax.sensor.noise.fallback`).

- `is_dark_frame(mosaic, black, white)`: no light. Per CFA site its median lies within
  `DARK_LEVEL_MAX` of the range of the tag, at most `CLIPPED_FRACTION` of its pixels sit at raw 0
  (a clipped frame's moments are biased) and at most `OUTLIER_FRACTION` lie beyond `OUTLIER_SIGMAS`
  (hot pixels are rare; a light in a night scene is not), and its 8 x 8 block means (outliers set
  to the centre) spread no more than pixel noise allows: robust sd at most `STRUCTURE_RATIO` x sd / 8
  and the 0.1-99.9 percentile range at most 10 x that, sd from differences of horizontal
  neighbours of the site (which a scene's structure does not raise). Row or column banding passes (a block mean
  of 8 rows carries a row offset's variance / 8, which the ratio allows).
- `dark_frame_statistics(mosaic)`: per site the mean and the variance about the frame's own mean,
  hot pixels left out (iterated clipping at `OUTLIER_SIGMAS`, whose truncation of Gaussian values
  lowers the variance by under 1e-7), and the share of that variance in row and column means
  (banding), all in DN.
- `read_from_dark_frames(stats, black, white)`: pooled over frames, (black (4,) DN, read (4,)
  normalised, rounding included as in a NoiseProfile tag). The rounding is undone exactly
  (`quantisation.variance_before_rounding` at the frames' mean, which for a read noise under
  0.5 DN differs from subtracting 1/12 DN^2) and 1/12 DN^2 put back, so that the profile's single
  removal of the rounding (`quantisation.without_quantisation`) leaves the variance whose rounding
  at the same level reproduces the dark frames' integers.

The audit's `g2r_jax.audit.black_evidence.is_dark_frame` detects dark frames for the black-level
cause by the same idea; the two could share this module.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from g2r_jax.sensor.noise import quantisation as _quantisation

DARK_LEVEL_MAX = 0.05      # median within this fraction of the range of the tag
STRUCTURE_RATIO = 3.0      # block-mean spread at most this many times what pixel noise gives
CLIPPED_FRACTION = 1e-3    # more pixels than this at raw 0: the frame's moments are biased
OUTLIER_SIGMAS = 6.0       # hot pixels: beyond this many sd of the site's centre
OUTLIER_FRACTION = 2e-3    # more outliers than this: scene content, not hot pixels
BLOCK = 8
SITES = ((0, 0), (0, 1), (1, 0), (1, 1))


def _site_planes(mosaic) -> list:
    m = np.asarray(mosaic)
    h, w = m.shape[0] // 2 * 2, m.shape[1] // 2 * 2
    return [m[dy:h:2, dx:w:2].astype(np.float64) for dy, dx in SITES]


def clipped_moments(values, sigmas: float = OUTLIER_SIGMAS, iterations: int = 20):
    """(mean, variance, inlier mask) of `values` with outliers left out: values beyond `sigmas`
    sd of the mean of the kept ones, iterated from the median and the interquartile spread (or
    the sd where integer data of under 1 DN make the quartiles coincide)."""
    v = np.asarray(values, np.float64).ravel()
    centre = np.median(v)
    q1, q3 = np.percentile(v, [25, 75])
    sd = (q3 - q1) / 1.349 if q3 > q1 else np.sqrt(np.mean((v - centre) ** 2 * (np.abs(v - centre) <= 3)))
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


def is_dark_frame(mosaic, black_level, white_level) -> bool:
    """True for a frame without light (see the module docstring)."""
    m = np.asarray(mosaic)
    if m.ndim != 2 or min(m.shape) < 2 * BLOCK:
        return False
    if np.mean(m == 0) > CLIPPED_FRACTION:
        return False
    black = np.resize(np.asarray(black_level, np.float64).reshape(-1), 4)
    span = float(white_level) - black
    step = max(1, int(np.sqrt(m.size / 4 / 250_000)))     # large files: a strided subset of rows will do
    for p, plane in enumerate(_site_planes(m)):
        plane = plane[::step]
        if abs(np.median(plane) - black[p]) > DARK_LEVEL_MAX * span[p]:
            return False
        centre, variance, keep = clipped_moments(plane)
        if variance <= 0 or np.mean(~keep) > OUTLIER_FRACTION:
            return False
        h, w = plane.shape[0] // BLOCK * BLOCK, plane.shape[1] // BLOCK * BLOCK
        if h == 0 or w == 0:
            return False
        clean = np.where(keep, plane, centre)[:h, :w]
        blocks = clean.reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK).mean(axis=(1, 3)).ravel()
        # pixel noise from neighbour differences: a scene's structure (and row banding) cancels there
        _, difference_variance, _ = clipped_moments(np.diff(clean, axis=1))
        allowed = STRUCTURE_RATIO * np.sqrt(difference_variance / 2) / BLOCK
        q1, q3 = np.percentile(blocks, [25, 75])
        if (q3 - q1) / 1.349 > allowed or np.ptp(np.percentile(blocks, [0.1, 99.9])) > 10 * allowed:
            return False
    return True


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
    for p, plane in enumerate(_site_planes(mosaic)):
        centre, variance, keep = clipped_moments(plane)
        out["mean"][p], out["variance"][p] = centre, variance
        out["count"][p], out["hot"][p] = keep.sum(), (~keep).sum()
        clean = np.where(keep, plane, centre) - centre
        rows, cols = clean.mean(axis=1), clean.mean(axis=0)
        out["banding"][p] = (max(rows.var() - variance / plane.shape[1], 0.0)
                             + max(cols.var() - variance / plane.shape[0], 0.0))
    return DarkFrameStatistics(**out)


@dataclasses.dataclass(frozen=True)
class DarkFrameReadNoise:
    """What dark frames say, per CFA site (4,): `black_dn` their mean level; `variance_dn2` the
    variance of their integers; `read` the read term in normalised units as a NoiseProfile tag
    holds it (1/12 DN^2 of rounding included, see the module docstring); `banding_share` the
    part of the variance in row/column means; `hot_fraction`; `n_frames`."""

    black_dn: np.ndarray
    variance_dn2: np.ndarray
    read: np.ndarray
    banding_share: np.ndarray
    hot_fraction: float
    n_frames: int


def read_from_dark_frames(statistics, black_level, white_level) -> DarkFrameReadNoise:
    """Pool several frames' `DarkFrameStatistics` (pixel-weighted means of their means and
    variances) into a `DarkFrameReadNoise` for the levels `black_level` (4,) / `white_level` of
    the profile (its normalisation span)."""
    if not statistics:
        raise ValueError("no dark frames to measure the read noise from")
    counts = np.stack([s.count for s in statistics])
    weights = counts / counts.sum(axis=0)
    mean = (weights * np.stack([s.mean for s in statistics])).sum(axis=0)
    variance = (weights * np.stack([s.variance for s in statistics])).sum(axis=0)
    banding = (weights * np.stack([s.banding for s in statistics])).sum(axis=0)
    black = np.resize(np.asarray(black_level, np.float64).reshape(-1), 4)
    span = float(white_level) - black
    before = np.array([np.mean([_quantisation.variance_before_rounding(s.variance[p], s.mean[p])
                                for s in statistics]) for p in range(4)])
    read = (before + 1.0 / 12.0) / span**2
    hot = float(np.sum([s.hot.sum() for s in statistics]) / np.sum([s.count.sum() + s.hot.sum() for s in statistics]))
    return DarkFrameReadNoise(black_dn=mean, variance_dn2=variance, read=read,
                              banding_share=np.where(variance > 0, banding / np.maximum(variance, 1e-300), 0.0),
                              hot_fraction=hot, n_frames=len(statistics))


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
