"""The noise of a burst (several frames of one static scene) from the pixels' variation over time:
no scene texture in it, and levels down to the scene's darkest content (issue 29).

Photon transfer (Janesick, *Photon Transfer: DN -> lambda*, SPIE 2007, ch. 4, and EMVA 1288
release 4.0, sec. 6): each pixel's variance over the frames against its mean, binned by level.
Flat blocks of single frames (`estimation`) keep the texture that passes their selection (on the
S20 FE-like bursts of `benchmarks/read_noise_dark_frames.py`, 2-15 % above the truth in most bins
and up to x40 in a few), and their S x + O line's intercept, the read term, is an extrapolation
from those bins. Here:

- the frames are split into two halves (even, odd); pixels are binned by their mean over one half
  and their variance taken over the other, and the other way round: the binning cannot select
  the noise it measures (binning by the same frames' mean puts pixels whose noise lifted them
  into a higher bin, and their variance with them). For variance = S x + O, linear in x, the
  bin's mean variance and mean level over the other half are then unbiased for one point of the
  line.
- bins: `N_BINS` geometric in level from 2^-11 of the range up, plus one for the dark floor;
  pixels of a frame at raw 0 or at the white level in any frame are left out, as are bins with
  fewer than `MIN_PIXELS` pixels.
- fit: S x + O per CFA site by weighted least squares (weights 1 / SE^2 of each bin's variance,
  from the spread of the pixels' variances), S, O >= 0 (scipy `lsq_linear`).

`is_static_burst(mosaics)` tells a burst from unrelated files: the frames have one shape, and each
frame minus the frames' median has no structure (its 8 x 8 block means spread no more than
`STRUCTURE_RATIO` x its pixel sd / 8, as pure noise), so the scene did not move and the exposure
did not change. The read term holds the rounding to DN (1/12 DN^2), as a NoiseProfile tag does.
It is temporal noise only: a sensor's dark fixed pattern (DSNU) is part of a dark frame's spatial
variance but not of this (`g2r_jax.sensor.dark_frames` measures it where dark frames are at hand).
"""

from __future__ import annotations

import numpy as np

MIN_FRAMES = 4
STRUCTURE_RATIO = 3.0
N_BINS = 24
MIN_PIXELS = 200
SITES = ((0, 0), (0, 1), (1, 0), (1, 1))


def _planes(mosaics, p):
    dy, dx = SITES[p]
    return np.stack([np.asarray(m)[dy::2, dx::2] for m in mosaics]).astype(np.float64)


def is_static_burst(mosaics) -> bool:
    """True for at least MIN_FRAMES frames of one shape and one static scene (module docstring)."""
    if len(mosaics) < MIN_FRAMES or len({np.shape(m) for m in mosaics}) != 1 or min(np.shape(mosaics[0])) < 32:
        return False
    for p in range(4):
        stack = _planes(mosaics, p)
        median = np.median(stack, axis=0)
        for frame in stack:
            d = frame - median
            q1, q3 = np.percentile(d, [25, 75])
            sd = (q3 - q1) / 1.349 if q3 > q1 else d.std()
            h, w = d.shape[0] // 8 * 8, d.shape[1] // 8 * 8
            blocks = d[:h, :w].reshape(h // 8, 8, w // 8, 8).mean(axis=(1, 3))
            b1, b3 = np.percentile(blocks, [25, 75])
            if sd <= 0 or (b3 - b1) / 1.349 > STRUCTURE_RATIO * sd / 8:
                return False
    return True


def temporal_bins(mosaics, black_level, white_level, *, n_bins: int = N_BINS, min_pixels: int = MIN_PIXELS):
    """(signal (4, B), variance (4, B), se (4, B)) normalised, NaN where a bin has too few pixels."""
    black = np.resize(np.asarray(black_level, np.float64).reshape(-1), 4)
    span = float(white_level) - black
    edges = np.concatenate([[-np.inf], np.geomspace(2.0**-11, 1.0, n_bins)])
    out = [np.full((4, len(edges) - 1), np.nan) for _ in range(3)]
    for p in range(4):
        stack = _planes(mosaics, p)
        usable = np.all((stack > 0) & (stack < float(white_level)), axis=0)
        x = (stack - black[p]) / span[p]
        halves = (x[0::2], x[1::2])
        sums = np.zeros((3, len(edges) - 1))
        squares = np.zeros(len(edges) - 1)
        for select, measure in ((0, 1), (1, 0)):
            level = halves[select].mean(axis=0)[usable]
            signal = halves[measure].mean(axis=0)[usable]
            variance = halves[measure].var(axis=0, ddof=1)[usable]
            index = np.searchsorted(edges, level, side="right") - 1
            ok = (index >= 0) & (index < len(edges) - 1)
            n = len(edges) - 1
            sums[0] += np.bincount(index[ok], minlength=n)
            sums[1] += np.bincount(index[ok], signal[ok], minlength=n)
            sums[2] += np.bincount(index[ok], variance[ok], minlength=n)
            squares += np.bincount(index[ok], variance[ok] ** 2, minlength=n)
        count = sums[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            mean_variance = sums[2] / count
            spread = squares / count - mean_variance**2
            enough = count >= min_pixels
            out[0][p] = np.where(enough, sums[1] / count, np.nan)
            out[1][p] = np.where(enough, mean_variance, np.nan)
            out[2][p] = np.where(enough, np.sqrt(np.maximum(spread, 0) / count), np.nan)
    return tuple(out)


def fit_temporal_shot_read(mosaics, black_level, white_level):
    """(shot (4,), read (4,)) of variance = shot x + read over a static burst's frames (module
    docstring); NaN at a site with fewer than 2 bins."""
    from scipy.optimize import lsq_linear

    signal, variance, se = temporal_bins(mosaics, black_level, white_level)
    shot, read = np.full(4, np.nan), np.full(4, np.nan)
    for p in range(4):
        ok = np.isfinite(variance[p]) & (se[p] > 0) & (variance[p] > 0)
        if ok.sum() < 2:
            continue
        x = np.maximum(signal[p, ok], 0.0)
        weight = 1.0 / se[p, ok]
        design = np.stack([x, np.ones_like(x)], 1) * weight[:, None]
        scale = np.array([1.0 / max(np.max(design[:, 0]), 1e-300), 1.0 / np.max(design[:, 1])])
        fitted = lsq_linear(design * scale, variance[p, ok] * weight, bounds=(0, np.inf)).x * scale
        shot[p], read[p] = fitted
    return shot, read
