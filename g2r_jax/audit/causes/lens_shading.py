"""`lens_shading`: radial fall-off of the raw signal (vignetting, colour shading).

Measures the corner log gain from the median radial gradient of log brightness per ring
(`stats.shading_profile`), per CFA position; extension: `SensorEffects.shading`
(gain 1 + a1 r^2 + a2 r^4, one fall-off per colour).

Radial gradient symmetry holds for scenes on average, not for every scene: one scene's layout
(a bright object off centre, texture that the plane sampling aliases) reads as a fall-off of
several tenths in some channels (synthetic dim bursts of one textured scene: 0.09-0.51 against
dead-leaves simulations). The cause is therefore tested on MIN_SCENES different scenes or more
(the frames of a burst are one scene).
"""

from __future__ import annotations

import numpy as np

from g2r_jax.audit.causes.base import Cause, as_profile_dtype, effects_replaced, per_colour


def shading_fit(profile, delta_log_corner) -> np.ndarray:
    """Per position (a1, a2) so that 1 + a1 t + a2 t^2 ~ old gain(t) * exp(delta * t), t = r^2."""
    t = np.linspace(0, 1, 21)
    old = np.asarray(profile.effects.shading, np.float64)
    design = np.stack([t, t**2], 1)
    out = np.zeros((4, 2))
    for p in range(4):
        target = (1 + old[p, 0] * t + old[p, 1] * t**2) * np.exp(delta_log_corner[p] * t) - 1
        out[p] = np.linalg.lstsq(design, target, rcond=None)[0]
    return out


class LensShading(Cause):
    name = "lens_shading"
    statistic = ("log gain at the corners from the median radial gradient of log brightness per ring, per "
                 "CFA position (one fitted fall-off per colour)")
    metric = "rms difference of corner log gain"
    key = "shading"
    floor, tolerance = 0.005, 0.05
    min_scenes = 4
    unit = "corner gain left after the file's own GainMap (1 = none)"

    def user_units(self, values, files):
        return np.exp(values)

    def fit(self, measured, simulated, profile, *, seed=0):
        shading = shading_fit(profile, per_colour(profile, self.mean_difference(measured, simulated, profile)))
        return {"shading": shading.tolist(), "corner_gain": (1 + shading.sum(1)).tolist()}

    def apply(self, profile, params):
        return effects_replaced(profile, shading=as_profile_dtype(profile, params["shading"]))


CAUSE = LensShading()
