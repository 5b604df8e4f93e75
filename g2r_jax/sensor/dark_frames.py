"""The read noise and the black level per CFA site that dark frames give a profile (issue 29).

A dark frame (a capture with the lens capped) holds, per CFA site, the black level, the read noise
(temporal noise, the dark signal's fixed pattern, row/column banding) and the rounding to DN:
what a simulated black frame must hold. Measured directly there, the read term needs no
extrapolation of a noise level function to zero signal, whose intercept the scene's texture and
the level bins' spread bias (`g2r_jax.sensor.noise.fallback`).

Dark frames are recognised and measured by the measurement toolkit
(`g2r_jax.measure.dark_frames`: `find_dark_frames`, `is_dark_frame`, `dark_frame_statistics`),
which the audit's black-level evidence uses too. Here:

- `read_from_dark_frames(stats, black, white)`: pooled over frames, (black (4,) DN, read (4,)
  normalised, rounding included as in a NoiseProfile tag). The rounding is undone exactly
  (`quantisation.variance_before_rounding` at the frames' mean, which for a read noise under
  0.5 DN differs from subtracting 1/12 DN^2) and 1/12 DN^2 put back, so that the profile's single
  removal of the rounding (`quantisation.without_quantisation`) leaves the variance whose rounding
  at the same level reproduces the dark frames' integers.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from g2r_jax.sensor.noise import quantisation as _quantisation


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
