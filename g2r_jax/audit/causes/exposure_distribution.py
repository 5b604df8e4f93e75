"""`exposure_distribution`: the files' brightness spread differs from the profile's exposure model.

Measures the mean log2 signal of the image centre (`stats.brightness`); extension:
`ExposureModel.log2_mean`, `log2_std`. Its discrepancy compares means and standard deviations.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.profile import schema as _profile
from g2r_jax.audit.causes.base import Cause, as_profile_dtype, quiet_nanmean


class ExposureDistribution(Cause):
    name = "exposure_distribution"
    statistic = "mean log2 signal of the image centre (well-exposed pixels), per file"
    metric = "distance of (mean, std) of log2 centre brightness"
    key = "brightness"
    floor, tolerance = 0.01, 0.1
    unit = "log2 brightness of the image centre (stops)"

    def component_labels(self, k, profile=None):
        return ["centre"]

    def fit(self, measured, simulated, profile, *, seed=0):
        m = self.vectors(measured, profile)[:, 0]
        s = self.vectors(simulated, profile)[:, 0]
        old_std = float(profile.exposure.log2_std)
        if np.isfinite(m).sum() >= 2 and np.isfinite(s).sum() >= 2:
            std = np.sqrt(max(old_std**2 + np.nanvar(m, ddof=1) - np.nanvar(s, ddof=1), 0.0))
        else:   # one file says nothing about the spread between files (its variance would be NaN)
            std = old_std
        return {"log2_mean": float(profile.exposure.log2_mean) + float(np.nanmean(m) - np.nanmean(s)),
                "log2_std": float(std)}

    def apply(self, profile, params):
        exposure = _profile.replace(profile.exposure, log2_mean=as_profile_dtype(profile, params["log2_mean"]),
                                    log2_std=as_profile_dtype(profile, params["log2_std"]))
        return _profile.replace(profile, exposure=exposure)

    def discrepancy(self, measured, simulated, profile, *, seed=0):
        m, s = self.vectors(measured, profile), self.vectors(simulated, profile)
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            difference = np.nan_to_num(quiet_nanmean(m) - quiet_nanmean(s))
            difference = np.append(difference, np.nan_to_num(np.nanstd(m, 0, ddof=1) - np.nanstd(s, 0, ddof=1)))
        return float(np.sqrt(np.mean(difference**2)))


CAUSE = ExposureDistribution()
