"""`noise_correlation`: the noise is not spatially white (denoising, compression, demosaicing).

What it measures: log of robust var(lag-2 second difference) / var(lag-1 second difference) in
flat regions (`stats.noise_correlation`; 0 for white noise, whatever the scene's linear shading),
tested over files (or, for few files, against the spread of simulated ones).

Extension: a 3 x 3 correlation kernel per CFA position (`NoiseModel.correlation_kernel`).
- Large files (their own noise evidence, `stats.LARGE_BLOCKS`): the kernel and its share by
  signal level (`correlation_knots`, `correlation_weight`; `sensor.noise.extension.fit_correlation_by_level`)
  fitted on the lag statistics of half A of the largest file's tiles (measured with its noise
  level function), so that noise smoothed only above some level (a phone or a lossy raw codec
  that denoises there) is simulated white below it. Held-out: the RMS, over the signal bins of
  half B of the held-out files (or of the one file) and the 12 lags of a 5 x 5 window, of the
  measured autocorrelation minus the one the profile simulates at that level, before and after;
  closed form, as `noise_model`'s.
- Small files: no extension yet (the fit is the identity kernel, which changes nothing, so a
  significant difference stays unexplained): they carry no noise evidence by level, and the scalar
  statistic reads a kernel differently at different noise levels (the flat-region selection keeps
  the pixels whose low-frequency noise happens to be small: a kernel that moves it by 0.13 at one
  noise level moved it by 0.004 at another).
"""

from __future__ import annotations

import numpy as np

from g2r_jax.audit.causes.base import Cause, as_profile_dtype
from g2r_jax.audit.stats import LARGE_BLOCKS

MIN_BLOCKS = 30   # bins of fewer blocks say little about 12 lags (the level function asks as many)


def _large(files) -> list:
    return [f for f in files if f.get("nlf") is not None and f.get("blocks", 0) >= LARGE_BLOCKS]


def _above_black(profile, f, signal):
    from g2r_jax.audit.causes.noise_model import above_black

    return above_black(profile, f, signal)


def measured_autocorrelation(f, half: str):
    """(rho (4, B, 13), counts (4, B), signal (4, B)) of one half of a file's tiles: each bin's lag
    statistics over its lag-0 one (`NoiseLevelEstimate.autocovariance`); NaN where unusable."""
    e = f["nlf"][half]
    c = np.asarray(e.autocovariance, np.float64)
    counts = np.asarray(e.counts)
    with np.errstate(invalid="ignore", divide="ignore"):
        usable = (counts >= MIN_BLOCKS) & np.isfinite(c[..., 0]) & (c[..., 0] > 0)
        rho = np.where(usable[..., None], c / c[..., :1], np.nan)
    return rho, counts, np.where(usable, e.signal, np.nan)


def autocorrelation_error(profile, files, half: str) -> float:
    """RMS over bins, positions and the 12 non-zero lags of measured - simulated autocorrelation."""
    from g2r_jax.sensor.noise.extension import autocorrelation_at_levels

    errors = []
    for f in files:
        rho, _, signal = measured_autocorrelation(f, half)
        model = autocorrelation_at_levels(profile.noise, np.nan_to_num(_above_black(profile, f, signal)))
        d = (rho - model)[..., 1:]
        errors.append(d[np.isfinite(d)])
    values = np.concatenate(errors) if errors else np.zeros(0)
    return float(np.sqrt(np.mean(values**2))) if values.size else 0.0


class NoiseCorrelation(Cause):
    name = "noise_correlation"
    statistic = "log ratio of lag-2 to lag-1 second-difference variance in flat regions (0 for white noise)"
    metric = ("rms of measured - simulated noise autocorrelation at the 12 lags of a 5 x 5 window per signal "
              "bin of held-out regions")
    key = "noise_corr"
    floor, tolerance = 0.005, 0.05
    unit = "var(lag-2 second difference) / var(lag-1 second difference) (1 = white)"
    region_heldout = True

    def user_units(self, values, files):
        return np.exp(values)

    def component_labels(self, k, profile=None):
        return ["rows"]

    def fit(self, measured, simulated, profile, *, seed=0):
        import dataclasses

        from g2r_jax.sensor.noise.extension import fit_correlation_by_level

        large = _large(measured)
        if large:
            f = max(large, key=lambda f: f["blocks"])
            half = f["nlf"]["A"]
            kernel, knots, weight = fit_correlation_by_level(
                dataclasses.replace(half, signal=_above_black(profile, f, half.signal)), min_blocks=MIN_BLOCKS)
            return {"kind": "by_level", "kernel": kernel.tolist(), "knots": knots.tolist(), "weight": weight.tolist(),
                    "fitted_on": str(f.get("name") or "file")}
        # small files carry no noise evidence by level: no kernel is fitted (the identity changes
        # nothing, so the difference stays unexplained); their scalar statistic depends on how much
        # of the correlated noise the flat-region selection keeps, which is not the kernel's alone
        identity = np.zeros((4, 3, 3))
        identity[:, 1, 1] = 1.0
        return {"kind": "kernel", "kernel": identity.tolist(), "note": "no noise evidence by level in small files"}

    def apply(self, profile, params):
        from g2r_jax.profile import schema as _profile

        by_level = params.get("kind") == "by_level"
        noise = _profile.replace(
            profile.noise, correlation_kernel=as_profile_dtype(profile, params["kernel"]),
            correlation_knots=as_profile_dtype(profile, params["knots"]) if by_level else None,
            correlation_weight=as_profile_dtype(profile, params["weight"]) if by_level else None)
        return _profile.replace(profile, noise=noise)

    def heldout(self, fit_files, held_files, simulated, profile, simulate_stats, *, seed=0):
        """Large files: fit on half A of the fit files' tiles, compare on half B of the held-out
        files, closed form (no re-simulation). Small files: re-simulation over files."""
        if not (_large(fit_files) and _large(held_files)):
            return super().heldout(fit_files, held_files, simulated, profile, simulate_stats, seed=seed)
        extended = self.apply(profile, self.fit(fit_files, simulated, profile, seed=seed))
        held = _large(held_files)
        return autocorrelation_error(profile, held, "B"), autocorrelation_error(extended, held, "B")


CAUSE = NoiseCorrelation()
