"""Photon transfer: the noise of a burst (frames of one static scene) from each pixel's variation
over time, with no model of the scene (Janesick, *Photon Transfer: DN -> lambda*, SPIE 2007,
ch. 2-5; EMVA 1288 release 4.0, sec. 6). Over the frames every pixel sees the same signal, so its
temporal mean is the signal and its temporal variance the noise at that signal, whatever the
scene's texture; fixed-pattern noise (a pixel's own gain and offset) is the same in every frame
and drops out. Every estimate here holds the rounding to DN (1/12 DN^2) as a NoiseProfile tag
does; callers that simulate their own rounding take it out (`g2r_jax.sensor.noise.quantisation`).

Three estimators, one per use, over one set of bin statistics (`bin_sums`, `bin_moments`):

- `temporal_bins` + `fit_shot_read` (profile fitting, `g2r_jax.sensor.noise.fallback`): the
  frames are split into two halves (even, odd); pixels are binned by their mean over one half and
  their variance taken over the other, and the other way round, so that the binning cannot
  select the noise it measures (binning by the same frames' mean puts pixels whose noise lifted
  them into a higher bin, and their variance with them). For variance = S x + O, linear in x, a
  bin's mean variance and mean level over the other half are then unbiased for one point of the
  line. Bins: `N_BINS` geometric in level from 2^-11 of the range up, plus one for the dark
  floor; pixels at raw 0 or at the white level in any frame are left out, as are bins with fewer
  than `MIN_PIXELS` pixels. Fit: S x + O per CFA site by weighted least squares (weights 1 / SE of
  each bin's variance), S, O >= 0 (scipy `lsq_linear`). On the S20 FE-like bursts of
  `benchmarks/read_noise_dark_frames.py` flat blocks of single frames kept 2-15 % of texture
  in most bins and up to x40 in a few; this has none.
- `temporal_nlf` (the audit's noise evidence): the noise level function itself, per CFA site
  and signal bin, for all pixels and for the two checkerboard halves of `TILE`-pixel tiles (the
  fit / held-out split of `audit.causes.noise_model`), each frame first scaled by its gain
  against the mean frame (least squares over the unclipped pixels), so that flicker and
  exposure steps do not add the scene's own variance.
- `regression_shot_read` (the downstream denoising test's truth): S and O by regression of the
  temporal variance s^2 on the temporal mean m over all pixels, the slope corrected for the noise
  in m (regression dilution; Fuller, *Measurement Error Models*, Wiley 1987, sec. 1.1).

It is temporal noise only: a sensor's dark fixed pattern (DSNU) is part of a dark frame's spatial
variance but not of this (`g2r_jax.measure.dark_frames` measures it where dark frames are at hand).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from g2r_jax.measure.planes import SITES

N_BINS = 24
MIN_PIXELS = 200
TILE = 32


def bin_sums(level, signal, variance, edges) -> np.ndarray:
    """(4, B) per bin of `edges` (by `level`): count, sum of signal, of variance, of variance^2."""
    n = len(edges) - 1
    index = np.searchsorted(edges, level, side="right") - 1
    ok = (index >= 0) & (index < n)
    index, signal, variance = index[ok], signal[ok], variance[ok]
    return np.stack([np.bincount(index, minlength=n), np.bincount(index, signal, minlength=n),
                     np.bincount(index, variance, minlength=n), np.bincount(index, variance**2, minlength=n)])


def bin_moments(sums, min_pixels: int = MIN_PIXELS, ddof: int = 0):
    """(signal, variance, se) of `bin_sums`: mean signal, mean variance and the standard error of
    the latter (the pixels' variances' sd with `ddof` / sqrt(count)); NaN below `min_pixels`."""
    count, signal, variance, squares = sums
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_variance = variance / count
        spread = (squares - count * mean_variance**2) / (count - ddof)
        enough = count >= min_pixels
        return (np.where(enough, signal / count, np.nan), np.where(enough, mean_variance, np.nan),
                np.where(enough, np.sqrt(np.maximum(spread, 0) / count), np.nan))


def temporal_bins(mosaics, black_level, white_level, *, n_bins: int = N_BINS, min_pixels: int = MIN_PIXELS):
    """(signal (4, B), variance (4, B), se (4, B)) normalised, by split halves (module docstring);
    NaN where a bin has too few pixels."""
    black = np.resize(np.asarray(black_level, np.float64).reshape(-1), 4)
    span = float(white_level) - black
    edges = np.concatenate([[-np.inf], np.geomspace(2.0**-11, 1.0, n_bins)])
    out = [np.full((4, len(edges) - 1), np.nan) for _ in range(3)]
    for p, (dy, dx) in enumerate(SITES):
        stack = np.stack([np.asarray(m)[dy::2, dx::2] for m in mosaics]).astype(np.float64)
        usable = np.all((stack > 0) & (stack < float(white_level)), axis=0)
        x = (stack - black[p]) / span[p]
        halves = (x[0::2], x[1::2])
        sums = 0.0
        for select, measure in ((0, 1), (1, 0)):
            sums = sums + bin_sums(halves[select].mean(axis=0)[usable], halves[measure].mean(axis=0)[usable],
                                   halves[measure].var(axis=0, ddof=1)[usable], edges)
        for k, values in enumerate(bin_moments(sums, min_pixels)):
            out[k][p] = values
    return tuple(out)


def fit_shot_read(signal, variance, se):
    """(shot (4,), read (4,)) of variance = shot x + read by weighted least squares over bins
    (weights 1 / se), both >= 0 (scipy `lsq_linear`); NaN at a site with fewer than 2 bins."""
    from scipy.optimize import lsq_linear

    shot, read = np.full(4, np.nan), np.full(4, np.nan)
    for p in range(4):
        ok = np.isfinite(variance[p]) & (se[p] > 0) & (variance[p] > 0)
        if ok.sum() < 2:
            continue
        x = np.maximum(signal[p, ok], 0.0)
        weight = 1.0 / se[p, ok]
        design = np.stack([x, np.ones_like(x)], 1) * weight[:, None]
        scale = np.array([1.0 / max(np.max(design[:, 0]), 1e-300), 1.0 / np.max(design[:, 1])])
        shot[p], read[p] = lsq_linear(design * scale, variance[p, ok] * weight, bounds=(0, np.inf)).x * scale
    return shot, read


@dataclasses.dataclass(frozen=True)
class TemporalNoise:
    """(4, B) per CFA position and signal bin (normalised units, signal above the BlackLevel tag):
    `signal` mean temporal mean, `variance` mean temporal variance, `se` its standard error,
    `counts` pixels; NaN where a bin has fewer than MIN_PIXELS pixels."""

    signal: np.ndarray
    variance: np.ndarray
    se: np.ndarray
    counts: np.ndarray
    frames: int


def _gain_equalised(frames, ok) -> np.ndarray:
    """Each frame divided by its least-squares gain against the mean frame over `ok` pixels."""
    mean = frames.mean(0)
    weight = np.where(ok, mean, 0.0)
    reference = max(float((mean * weight).sum()), 1e-30)
    for k in range(frames.shape[0]):
        gain = float((frames[k] * weight).sum() / reference)
        if gain > 0:
            frames[k] /= gain
    return frames


def temporal_nlf(frames, *, pedestal, clip, clip_low, edges) -> dict:
    """{"all", "A", "B"}: `TemporalNoise` of (n, 4, h, w) normalised frames above black.

    **Arguments:** `pedestal` (4,) normalised black above the tag (added back to the signal
    axis); `clip`, `clip_low` (4,) normalised levels above black where the data clips (pixels
    that reach either in any frame are left out); `edges` signal bin edges above the tag.
    """
    frames = np.array(frames, np.float32)
    ok = (frames.max(0) < np.asarray(clip, np.float32)[:, None, None]) & \
         (frames.min(0) > np.asarray(clip_low, np.float32)[:, None, None])
    frames = _gain_equalised(frames, ok)
    variance = frames.var(0, ddof=1).astype(np.float64)
    signal = frames.mean(0).astype(np.float64) + np.asarray(pedestal, np.float64)[:, None, None]
    _, h, w = signal.shape
    tiles = ((np.arange(h)[:, None] // TILE) + (np.arange(w)[None, :] // TILE)) % 2
    out = {}
    for half, select in (("all", np.ones((h, w), bool)), ("A", tiles == 0), ("B", tiles == 1)):
        sums = [bin_sums(signal[p][ok[p] & select], signal[p][ok[p] & select], variance[p][ok[p] & select], edges)
                for p in range(4)]
        moments = [bin_moments(s, MIN_PIXELS, ddof=1) for s in sums]
        out[half] = TemporalNoise(signal=np.stack([m[0] for m in moments]), variance=np.stack([m[1] for m in moments]),
                                  se=np.stack([m[2] for m in moments]), frames=frames.shape[0],
                                  counts=np.stack([s[0] for s in sums]).astype(int))
    return out


def regression_shot_read(planes, floor) -> tuple[np.ndarray, np.ndarray]:
    """(shot (4,), read (4,)) of variance = shot x + read from (n, 4, h, w) normalised frames, by
    regression of each pixel's temporal variance s^2 (ddof 1) on its temporal mean m over the
    pixels that never clip (below 0.98, above `floor` (4,)). For Gaussian noise s^2 and m are
    independent and E[s^2] = shot mu + read, but m holds the noise of a mean of n frames, which
    would flatten an ordinary fit; the slope is corrected by its known variance mean(s^2) / n:
    shot = cov(m, s^2) / (var(m) - mean(s^2) / n), read = mean(s^2) - shot mean(m) (Fuller 1987,
    sec. 1.1). NaN at a site whose pixels do not span a range of signals."""
    n = planes.shape[0]
    shot, read = np.full(4, np.nan), np.full(4, np.nan)
    for p in range(4):   # one CFA plane at a time: a 12-MP burst's float64 copies stay small
        plane = planes[:, p]
        usable = (plane.max(0) < 0.98) & (plane.min(0) > floor[p])
        m = plane.mean(0, dtype=np.float64)[usable]
        s2 = plane.var(0, ddof=1, dtype=np.float64)[usable]
        if m.size < 100:
            continue
        spread = m.var() - s2.mean() / n
        if spread <= 0:
            continue
        shot[p] = np.mean((m - m.mean()) * (s2 - s2.mean())) / spread
        read[p] = s2.mean() - shot[p] * m.mean()
    return shot, read
