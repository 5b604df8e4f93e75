"""`black_level`: the dark floor sits above (or below) the BlackLevel tag (a black pedestal).

Measures the dark floor (`stats.dark_floor`: 0.5th percentile of 4x4 block means) minus the
tag, as a fraction of the range; extension: `SensorEffects.black_pedestal` (DN per position).
"""

from __future__ import annotations

import numpy as np

from g2r_jax.audit.causes.base import Cause, as_profile_dtype, effects_replaced, file_spans, per_colour, span


class BlackLevel(Cause):
    name = "black_level"
    statistic = ("dark floor (0.5th percentile of 4x4 block means) minus the BlackLevel tag, fraction of "
                 "range, per CFA position")
    metric = "rms difference of the dark floor (fraction of range)"
    key = "dark_floor"
    floor, tolerance = 1e-4, 1e-3
    unit = "dark floor above the BlackLevel tag (DN)"

    def user_units(self, values, files):
        return values * file_spans(files)

    def fit(self, measured, simulated, profile, *, seed=0):
        # one added pedestal per colour: two noisy per-green estimates would leave a Gr/Gb offset
        # difference in the extended profile that reads as green imbalance in the next round
        delta = per_colour(profile, self.mean_difference(measured, simulated, profile) * span(profile))
        pedestal = np.asarray(profile.effects.black_pedestal, np.float64) + delta
        return {"black_pedestal_dn": pedestal.tolist(), "offset_fraction": float(np.mean(pedestal / span(profile)))}

    def apply(self, profile, params):
        return effects_replaced(profile, black_pedestal=as_profile_dtype(profile, params["black_pedestal_dn"]))


CAUSE = BlackLevel()
