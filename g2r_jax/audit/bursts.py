"""Bursts: several frames of one static scene among the measured files, and the noise they
measure without any model of the scene (photon transfer).

Photon transfer (Janesick, *Photon Transfer: DN -> lambda*, SPIE Press 2007, ch. 2-5): over the
frames of a burst every pixel sees the same signal, so its temporal mean is the signal and its
temporal variance is the noise at that signal, whatever the scene's texture; fixed-pattern
noise (a pixel's own gain and offset) is the same in every frame and drops out. Binned by the
temporal mean, the temporal variances give the noise level function directly: the gold standard
that single-frame estimators (flat blocks, `noise_estimation`) approximate.

- `find_bursts(files)`: groups of at least MIN_FRAMES measured files of one size and ISO whose
  thumbnails (`stats.thumbnail`) agree up to a global gain (correlation above MIN_CORRELATION);
  dark frames are never part of a burst.
- `temporal_nlf(frames, ...)`: the temporal noise level function of a burst, per CFA position
  and signal bin, for all pixels and for the two checkerboard halves of 32-pixel tiles ("A", "B",
  the fit / held-out split of `causes.noise_model`). Frame-to-frame exposure changes (flicker,
  auto exposure) would add the scene's own variance: each frame is first scaled by its gain
  against the mean frame (least squares over the unclipped pixels).
"""

from __future__ import annotations

import dataclasses

import numpy as np

MIN_FRAMES = 4
MIN_CORRELATION = 0.995
MAX_PIXELS = 3_000_000       # pixels per frame kept for the temporal statistics (whole rows, strided)
TILE = 32


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


MIN_PIXELS = 200


def _gain_free_correlation(a, b) -> float:
    a, b = np.asarray(a, np.float64).ravel(), np.asarray(b, np.float64).ravel()
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 16:
        return 0.0
    a, b = a[ok] - a[ok].mean(), b[ok] - b[ok].mean()
    norm = np.sqrt((a * a).sum() * (b * b).sum())
    return float((a * b).sum() / norm) if norm > 0 else 0.0


def find_bursts(files) -> list[list[int]]:
    """Index groups of `files` (their `stats.file_statistics`) that are bursts of one scene."""
    groups: list[list[int]] = []
    for i, f in enumerate(files):
        if f.get("dark_frame") or not np.all(np.isfinite(f.get("thumbnail", np.nan))):
            continue
        for group in groups:
            first = files[group[0]]
            same = (first["shape"] == f["shape"] and abs(first["iso"] - f["iso"]) <= 0.02 * max(first["iso"], 1.0)
                    and _gain_free_correlation(first["thumbnail"], f["thumbnail"]) >= MIN_CORRELATION)
            if same:
                group.append(i)
                break
        else:
            groups.append([i])
    return [g for g in groups if len(g) >= MIN_FRAMES]


def _stride(shape) -> int:
    return max(1, int(np.ceil(shape[0] * shape[1] / MAX_PIXELS)))


def frame_planes(mosaic, black_dn, white, pedestal_dn) -> np.ndarray:
    """(4, h, w) float32 planes above the sensor's black (tag + pedestal), normalised, of the
    rows `temporal_nlf` keeps (every `_stride`-th pair of rows)."""
    from g2r_jax.sensor.noise.estimation import to_normalised_planes

    m = np.asarray(mosaic)
    step = _stride(m.shape)
    if step > 1:
        m = m.reshape(m.shape[0] // 2, 2, m.shape[1])[::step].reshape(-1, m.shape[1])
    black = np.resize(np.asarray(black_dn, np.float64), 4)
    planes = to_normalised_planes(m, black, white)
    pedestal = np.resize(np.asarray(pedestal_dn, np.float64), 4) / (float(white) - black)
    return (planes - pedestal[:, None, None]).astype(np.float32)


def temporal_nlf(frames, *, pedestal, clip, clip_low, edges) -> dict:
    """{"all", "A", "B"}: `TemporalNoise` of (n, 4, h, w) frames above black (`frame_planes`).

    **Arguments:** `pedestal` (4,) normalised black above the tag (added back to the signal
    axis); `clip`, `clip_low` (4,) normalised levels above black where the data clips (pixels
    that reach either in any frame are left out); `edges` signal bin edges above the tag.
    """
    frames = np.asarray(frames, np.float32)
    n = frames.shape[0]
    mean = frames.mean(0)
    ok = (frames.max(0) < np.asarray(clip, np.float32)[:, None, None]) & \
         (frames.min(0) > np.asarray(clip_low, np.float32)[:, None, None])
    for k in range(n):   # each frame's gain against the mean frame: flicker and exposure steps out
        weight = np.where(ok, mean, 0.0)
        gain = float((frames[k] * weight).sum() / max(float((mean * weight).sum()), 1e-30))
        if gain > 0:
            frames[k] /= gain
    mean = frames.mean(0)
    variance = frames.var(0, ddof=1).astype(np.float64)
    signal = mean.astype(np.float64) + np.asarray(pedestal, np.float64)[:, None, None]
    _, h, w = mean.shape
    tiles = ((np.arange(h)[:, None] // TILE) + (np.arange(w)[None, :] // TILE)) % 2
    out = {}
    for half, select in (("all", np.ones((h, w), bool)), ("A", tiles == 0), ("B", tiles == 1)):
        nb = len(edges) - 1
        result = {k: np.full((4, nb), np.nan) for k in ("signal", "variance", "se")}
        counts = np.zeros((4, nb), int)
        for p in range(4):
            keep = ok[p] & select
            s, v = signal[p][keep], variance[p][keep]
            index = np.searchsorted(edges, s, side="right") - 1
            for b in range(nb):
                chosen = index == b
                c = int(chosen.sum())
                counts[p, b] = c
                if c >= MIN_PIXELS:
                    result["signal"][p, b] = s[chosen].mean()
                    result["variance"][p, b] = v[chosen].mean()
                    result["se"][p, b] = v[chosen].std(ddof=1) / np.sqrt(c)
        out[half] = TemporalNoise(counts=counts, frames=n, **result)
    return out
