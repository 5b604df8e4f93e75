"""`noise_correlation`: the noise is not spatially white (denoising, compression, demosaicing).

Measures log of robust var(lag-2 second difference) / var(lag-1 second difference) in flat
regions (`stats.noise_correlation`; 0 for white noise, whatever the scene's linear shading). No extension yet: a significant difference is
reported as unexplained.
"""

from __future__ import annotations

from g2r_jax.audit.causes.base import Cause


class NoiseCorrelation(Cause):
    name = "noise_correlation"
    statistic = "log ratio of lag-2 to lag-1 second-difference variance in flat regions (0 for white noise)"
    metric = ""
    key = "noise_corr"
    floor, tolerance = 0.005, 0.05
    extensible = False
    unit = "var(lag-2 second difference) / var(lag-1 second difference) (1 = white)"

    def user_units(self, values, files):
        import numpy as np
        return np.exp(values)

    def component_labels(self, k, profile=None):
        return ["rows"]


CAUSE = NoiseCorrelation()
