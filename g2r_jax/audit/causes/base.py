"""The interface every audit cause implements, and the defaults most causes share.

A cause is one thing a profile can get wrong about a camera. Its class says, in one place:

- what it measures: `statistic` (words), `vectors(files, profile)` -> (n_files, k) per-file
  statistic from the dicts of `stats.file_statistics`;
- how it is tested: `test(measured, simulated, profile, ...)` -> a finding dict; the default is
  the permutation maxT test over files of `vectors` (`significance.max_t_permutation`), with
  `floor` (resolution added to standard errors) and `tolerance` (smallest difference worth
  reporting, in the statistic's units);
- how its extension is fitted and applied: `fit(measured, simulated, profile)` -> JSON-ready
  params, `apply(profile, params)` -> the extended profile (`extensible = False` for a
  statistic with no extension yet: a significant difference is reported as unexplained);
- how the extension is validated: `metric` (words), `discrepancy(measured, simulated, profile)`
  and `heldout(...)` -> (before, after) on files (or regions) the fit did not see.
"""

from __future__ import annotations

import warnings

import numpy as np

from scipy import stats as _scipy_stats

from g2r_jax.audit import significance

MIN_FILES_PERMUTATION = 4   # below this, permutations over files cannot reach small p-values


def quiet_nanmean(values, axis=0):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(values, axis=axis)


def effects_replaced(profile, **changes):
    """The profile with some `SensorEffects` fields replaced."""
    from g2r_jax.profile import schema as _profile

    return _profile.replace(profile, effects=_profile.replace(profile.effects, **changes))


def as_profile_dtype(profile, values):
    import jax.numpy as jnp

    return jnp.asarray(values, profile.effects.black_pedestal.dtype)


def file_spans(files) -> np.ndarray:
    """(n, 4) WhiteLevel - BlackLevel in DN of each file (from its statistics)."""
    return np.stack([np.resize(np.asarray(f.get("span", 1.0), np.float64), 4) for f in files])


def span(profile) -> np.ndarray:
    """(4,) WhiteLevel - BlackLevel in DN."""
    return float(profile.white_level) - np.asarray(profile.black_level, np.float64)


def per_colour(profile, values) -> np.ndarray:
    """Average over the CFA positions of one colour (the two greens of a Bayer tile).

    Lens and colour shading is a property of the optics and the colour filter, so both green
    positions share one fall-off. Fitting them apart lets the noise of two estimates become a
    radial Gr/Gb gain difference in the extended profile, which the next round then "finds" as
    green imbalance; a Gr/Gb gain mismatch is `green_imbalance`'s parameter, not shading's.
    """
    cfa = np.asarray(profile.cfa_pattern)
    values = np.asarray(values, np.float64)
    return np.array([values[cfa == cfa[p]].mean() for p in range(len(values))])


class Cause:
    """Base class of the registered causes (see the module docstring for the contract)."""

    name: str = ""
    statistic: str = ""
    metric: str = ""
    floor: float = 0.0
    tolerance: float = 0.0
    key: str = ""                 # file_statistics key of the per-file vector (default `vectors`)
    extensible: bool = True       # has an extension (fit/apply); else significant = unexplained
    min_scenes: int = 1           # fewest independent scenes on which the statistic means something
    needs_outliers: bool = False  # its statistic needs stats.outliers on simulated files

    # -- what it measures
    def vectors(self, files: list, profile) -> np.ndarray:
        """(n_files, k) statistic of each file."""
        return np.stack([np.asarray(f[self.key], np.float64) for f in files])

    def vector_pair(self, measured: list, simulated: list, profile):
        """(measured (n, k), simulated (m, k)) statistics of both sets. A cause whose per-file
        statistic is centred on a reference drawn from both sets pooled (label-free, so the
        permutation test stays exact) overrides this; the default is `vectors` of each set."""
        return self.vectors(measured, profile), self.vectors(simulated, profile)

    def mean_difference(self, measured, simulated, profile) -> np.ndarray:
        """measured - simulated mean of the statistic (NaN components -> 0)."""
        m, s = self.vector_pair(measured, simulated, profile)
        return np.nan_to_num(quiet_nanmean(m) - quiet_nanmean(s))

    # -- how it is tested
    def test(self, measured, simulated, profile, *, n_permutations: int = 2000, seed: int = 0) -> dict:
        """A finding: cause, score, p, magnitude (in the statistic's units), statistic,
        evidence (words), difference (per component). Permutation maxT over files; with fewer
        than `MIN_FILES_PERMUTATION` measured files, the prediction-interval test instead; with
        fewer than `min_scenes`, not tested (score 0, p 1)."""
        if len(measured) < self.min_scenes:
            return {"cause": self.name, "score": 0.0, "p": 1.0, "magnitude": 0.0, "statistic": self.statistic,
                    "evidence": f"needs at least {self.min_scenes} different scenes, {len(measured)} given: not tested",
                    "difference": [], "tested": False}
        if len(measured) < MIN_FILES_PERMUTATION:
            return self.prediction_test(measured, simulated, profile)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m, s = self.vector_pair(measured, simulated, profile)
            test = significance.max_t_permutation(m, s, floor=self.floor, n_permutations=n_permutations,
                                                  seed=seed)
        finite = np.isfinite(test["difference"])
        magnitude = float(np.nanmax(np.abs(test["difference"]))) if np.any(finite) else 0.0
        evidence = (f"measured - simulated mean = {np.array2string(test['difference'], precision=5)}; "
                    f"max |t| = {test['score']:.2f}, permutation p = {test['p']:.4g}")
        return {"cause": self.name, "score": test["score"], "p": test["p"], "magnitude": magnitude,
                "statistic": self.statistic, "evidence": evidence,
                "difference": np.nan_to_num(test["difference"]).tolist()}

    def prediction_test(self, measured, simulated, profile) -> dict:
        """Few measured files against the spread of the simulated ones: per component
        t = (mean_m - mean_s) / sqrt(s_s^2 (1/n_m + 1/n_s) + floor^2), Student t with n_s - 1
        degrees of freedom (the prediction interval of a new observation, e.g. Hahn & Meeker,
        *Statistical Intervals*, 1991, ch. 4), Bonferroni over components. A statistic that
        describes the sensor varies little between simulated files, so one file has power;
        one that describes the scene (brightness) varies a lot, so it has little, as it should."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m, s = self.vector_pair(measured, simulated, profile)
            n_m, n_s = np.sum(np.isfinite(m), 0), np.sum(np.isfinite(s), 0)
            difference = np.nanmean(m, 0) - np.nanmean(s, 0)
            sd = np.nanstd(s, 0, ddof=1)
            se = np.sqrt(np.nan_to_num(sd) ** 2 * (1 / np.maximum(n_m, 1) + 1 / np.maximum(n_s, 1)) + self.floor**2)
            usable = (n_m >= 1) & (n_s >= 3) & np.isfinite(difference)
            t = np.where(usable, difference / se, 0.0)
        k = max(int(usable.sum()), 1)
        score = float(np.max(np.abs(t))) if t.size else 0.0
        p_components = 2 * _scipy_stats.t.sf(np.abs(t), np.maximum(n_s - 1, 1))
        p = float(min(1.0, k * np.min(np.where(usable, p_components, 1.0)))) if t.size else 1.0
        magnitude = float(np.max(np.abs(np.where(usable, difference, 0.0)))) if t.size else 0.0
        evidence = (f"measured - simulated mean = {np.array2string(np.where(usable, difference, np.nan), precision=5)} "
                    f"({int(n_m.max()) if n_m.size else 0} measured file(s) against {int(n_s.max()) if n_s.size else 0} "
                    f"simulated); max |t| = {score:.2f}, prediction-interval p = {p:.4g}")
        return {"cause": self.name, "score": score, "p": p, "magnitude": magnitude, "statistic": self.statistic,
                "evidence": evidence, "difference": np.nan_to_num(difference).tolist()}

    def is_significant(self, finding: dict, threshold: float) -> bool:
        return bool(finding["p"] < threshold and finding["magnitude"] >= self.tolerance)

    # -- the plot that makes the case (report.py draws it)
    unit: str = "statistic"

    def user_units(self, values: np.ndarray, files: list) -> np.ndarray:
        """The statistic in the units a user reads (override: DN, % of range, ratio)."""
        return values

    def component_labels(self, k: int, profile=None) -> list:
        """Names of a statistic's components for the report: the colour and the place in the 2 x 2
        CFA tile of per-position statistics ('R (0,0)'), else the component's index."""
        if k != 4:
            return [str(j) for j in range(k)]
        return position_labels(profile)

    def plot(self, measured, simulated, profile, extended=None) -> dict | None:
        """Plot data for the report: per component, measured against simulated files."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m, s = self.vector_pair(measured, simulated, profile)
            m, s = self.user_units(m, measured), self.user_units(s, simulated)
        return {"kind": "strip", "measured": np.asarray(m).tolist(), "simulated": np.asarray(s).tolist(),
                "unit": self.unit, "labels": self.component_labels(np.shape(m)[1], profile),
                "title": f"{self.name}: measured files against files simulated by the profile"}

    # -- how its extension is fitted and applied
    def fit(self, measured, simulated, profile, *, seed: int = 0) -> dict:
        raise NotImplementedError(f"{self.name} has no extension")

    def apply(self, profile, params: dict):
        raise NotImplementedError(f"{self.name} has no extension")

    # -- how the extension is validated
    def discrepancy(self, measured, simulated, profile, *, seed: int = 0) -> float:
        """How far simulated files are from measured ones in this statistic (lower is better):
        the RMS of the mean difference."""
        return float(np.sqrt(np.mean(self.mean_difference(measured, simulated, profile) ** 2)))

    def heldout(self, fit_files, held_files, simulated, profile, simulate_stats, *, seed: int = 0):
        """(before, after) discrepancy on `held_files` of the extension fitted on `fit_files`.
        `simulate_stats(profile, cause)` re-simulates the same scenes and draws with another profile."""
        params = self.fit(fit_files, simulated, profile, seed=seed)
        resimulated = simulate_stats(self.apply(profile, params), self.name)
        return (self.discrepancy(held_files, simulated, profile, seed=seed),
                self.discrepancy(held_files, resimulated, profile, seed=seed))


CFA_PLACES = ("(0,0)", "(0,1)", "(1,0)", "(1,1)")   # (row, column) in the 2 x 2 CFA tile


def position_labels(profile=None) -> list:
    """['R (0,0)', 'G (0,1)', ...]: the colour of each place in the 2 x 2 CFA tile (row, column),
    from the profile's CFA pattern; the places alone without a profile."""
    places = list(CFA_PLACES)
    pattern = getattr(profile, "cfa_pattern", None)
    if pattern is None:
        return places
    colours = ["R", "G", "B"]
    return [f"{colours[int(c)] if 0 <= int(c) < 3 else c} {place}" for c, place in zip(np.asarray(pattern).ravel(), places)]
