"""Burst frames put above the sensor's black the audit's way (`frame_planes`), for the toolkit's
burst finding (`g2r_jax.measure.bursts.find_bursts`) and temporal noise level function
(`g2r_jax.measure.photon_transfer.temporal_nlf`: per CFA position and signal bin, for all pixels
and for the two checkerboard halves "A", "B" of the fit / held-out split of `causes.noise_model`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MAX_PIXELS", "frame_planes"]

MAX_PIXELS = 3_000_000       # pixels per frame kept for the temporal statistics (whole rows, strided)


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
