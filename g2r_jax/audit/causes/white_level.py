"""`white_level`: the sensor saturates below WhiteLevel (early clipping).

Measures the level of the saturation spike above the sensor's black (`stats.clipping_level`, less the
pedestal: `stats.file_statistics`), fraction of range; extension: `SensorEffects.clip_level`.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.audit.causes.base import Cause, as_profile_dtype, effects_replaced, quiet_nanmean


class WhiteLevel(Cause):
    name = "white_level"
    statistic = "saturation spike level above black, fraction of range, per CFA position"
    metric = "rms difference of the clipping level (fraction of range)"
    key = "clip"
    floor, tolerance = 3e-4, 3e-3
    unit = "clipping level above black (% of range)"

    def user_units(self, values, files):
        return 100 * values

    def fit(self, measured, simulated, profile, *, seed=0):
        """The profile's clip level moved by the median difference over the CFA positions that
        clip in both sets: a position without a saturation spike (a colour the scenes never drive
        to the top) says nothing about the level and must not pull the median towards 0."""
        difference = (quiet_nanmean(self.vectors(measured, profile))
                      - quiet_nanmean(self.vectors(simulated, profile)))
        difference = difference[np.isfinite(difference)]
        level = float(profile.effects.clip_level) + (float(np.median(difference)) if difference.size else 0.0)
        return {"clip_level": float(min(level, 1.0))}

    def apply(self, profile, params):
        return effects_replaced(profile, clip_level=as_profile_dtype(profile, params["clip_level"]))


CAUSE = WhiteLevel()
