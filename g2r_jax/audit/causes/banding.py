"""`banding`: per-row / per-column offsets (fixed-pattern readout noise).

Measures the variance of row and column offsets from the split-half covariance of row (column)
medians (`stats.banding`); extension: `SensorEffects.row_noise_std`, `column_noise_std`.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.audit.causes.base import Cause, as_profile_dtype, effects_replaced, file_spans


class Banding(Cause):
    name = "banding"
    statistic = "variance of row and column offsets from split-half covariance of row (column) medians"
    metric = "rms difference of row/column offset variance"
    key = "band"
    floor, tolerance = 1e-8, 1e-6
    unit = "std of row / column offsets (DN)"

    def user_units(self, values, files):
        return np.sqrt(np.maximum(values, 0)) * file_spans(files).mean(1, keepdims=True)

    def component_labels(self, k, profile=None):
        return ["rows", "columns"]

    def fit(self, measured, simulated, profile, *, seed=0):
        delta = self.mean_difference(measured, simulated, profile)
        effects = profile.effects
        old = np.array([float(effects.row_noise_std), float(effects.column_noise_std)])
        std = np.sqrt(np.maximum(old**2 + delta, 0.0))
        return {"row_noise_std": float(std[0]), "column_noise_std": float(std[1])}

    def apply(self, profile, params):
        return effects_replaced(profile, row_noise_std=as_profile_dtype(profile, params["row_noise_std"]),
                                column_noise_std=as_profile_dtype(profile, params["column_noise_std"]))


CAUSE = Banding()
