"""`exposure_distribution`: the files' brightness spread differs from the profile's exposure model.

Measures the mean log2 signal of the image centre (`stats.brightness`); extension:
`ExposureModel.log2_mean`, `log2_std`. Its discrepancy compares means and standard deviations.

Frames without light (dark frames: `stats.file_statistics`'s `dark_frame`, and frames whose
centre stays within the read noise, which is what a dark frame clipped at raw 0 looks like to
`measure.dark_frames.is_dark_frame`, e.g. gopro_hero6's with BlackLevel 0) have no exposure: their
brightness is log2 of the noise floor, ~10 stops below any scene. They are left out (NaN). Three
such frames among 24 scenes of a gopro_hero6 set shifted by +2.9 stops read a difference of 0.99
stops at |t| = 1.24 (not significant) instead of the scenes' 2.3 stops.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.profile import schema as _profile
from g2r_jax.audit.causes.base import Cause, as_profile_dtype, quiet_nanmean

LIGHTLESS_SIGMAS = 3.0   # a centre whose 70th percentile is below this many read-noise sd saw no light


def read_noise_sd(profile, iso: float) -> float:
    """The largest read-noise sd over the CFA positions at `iso` (normalised units)."""
    isos = np.asarray(profile.noise.iso, np.float64)
    read = np.asarray(profile.noise.read, np.float64)
    return float(np.sqrt(max(np.interp(iso, isos, read[:, p]) for p in range(read.shape[1]))))


def saw_light(f, profile) -> bool:
    """False for a dark frame, or a file whose centre's 70th percentile (`stats.centre_quantiles`,
    above the sensor's black) is within LIGHTLESS_SIGMAS read-noise sd of black."""
    if f.get("dark_frame"):
        return False
    quantiles = f.get("centre_quantiles")
    if quantiles is None:
        return True
    return bool(np.max(quantiles) > LIGHTLESS_SIGMAS * read_noise_sd(profile, f["iso"]))


class ExposureDistribution(Cause):
    name = "exposure_distribution"
    statistic = "mean log2 signal of the image centre (well-exposed pixels), per file"
    metric = "distance of (mean, std) of log2 centre brightness"
    key = "brightness"
    floor, tolerance = 0.01, 0.1
    unit = "log2 brightness of the image centre (stops)"

    def vectors(self, files, profile):
        """(n, 1) centre brightness; NaN for frames without light (`saw_light`)."""
        return np.array([[float(f[self.key][0]) if saw_light(f, profile) else np.nan] for f in files])

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
