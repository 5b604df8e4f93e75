"""`green_imbalance`: the two green sites of the Bayer tile respond differently (Gr/Gb).

Measures the median log(G2/G1) of 4x4 blocks over a dark floor common to both greens
(`stats.green_ratio`); extension: `SensorEffects.channel_gain` of the second green.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.audit.causes.base import Cause, as_profile_dtype, effects_replaced


class GreenImbalance(Cause):
    name = "green_imbalance"
    statistic = ("median log(G2/G1) of 4x4 blocks of the two green CFA positions, over one dark floor "
                 "common to both greens")
    metric = "difference of median log(G2/G1)"
    key = "green"
    floor, tolerance = 5e-4, 5e-3
    unit = "median G2 / G1 of 4x4 blocks"

    def user_units(self, values, files):
        return np.exp(values)

    def component_labels(self, k, profile=None):
        return ["G2 / G1"]

    def fit(self, measured, simulated, profile, *, seed=0):
        greens = np.flatnonzero(np.asarray(profile.cfa_pattern) == 1)[:2]
        gain = np.asarray(profile.effects.channel_gain, np.float64)
        delta = self.mean_difference(measured, simulated, profile)[0]
        ratio = float(np.exp(delta) * gain[greens[1]] / gain[greens[0]])
        return {"green2_over_green1": ratio, "positions": [int(g) for g in greens]}

    def apply(self, profile, params):
        gain = np.asarray(profile.effects.channel_gain, np.float64).copy()
        g1, g2 = params["positions"]
        gain[g2] = gain[g1] * params["green2_over_green1"]
        return effects_replaced(profile, channel_gain=as_profile_dtype(profile, gain))


CAUSE = GreenImbalance()
