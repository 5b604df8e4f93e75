"""`diagnose`: measured DNGs + a profile -> findings (cause, significance, fitted extension,
held-out gain) and an extended profile. Steps follow issue 3: statistics on measured and
simulated files, a test per statistic, a cause per significant difference, an extension fitted
on fit splits and kept only if it lowers the held-out discrepancy.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from . import extensions, gain, loading, measures, significance, simulate, stats
from .scenes import scene_set
from .vocabulary import CAUSES, FLOOR, STATISTICS, TOLERANCE, UNEXPLAINED

_MEAN_TESTS = ("exposure_distribution", "noise_model", "black_level", "white_level", "green_imbalance",
               "lens_shading", "banding")


def _mean_finding(cause, measured, simulated, profile, n_permutations, seed):
    m = measures.vectors(cause, measured, profile)
    s = measures.vectors(cause, simulated, profile)
    test = significance.max_t_permutation(m, s, floor=FLOOR[cause], n_permutations=n_permutations, seed=seed)
    magnitude = float(np.nanmax(np.abs(test["difference"]))) if np.any(np.isfinite(test["difference"])) else 0.0
    evidence = (f"measured - simulated mean = {np.array2string(test['difference'], precision=5)}; "
                f"max |t| = {test['score']:.2f}, permutation p = {test['p']:.4g}")
    return {"cause": cause, "score": test["score"], "p": test["p"], "magnitude": magnitude,
            "statistic": STATISTICS[cause], "evidence": evidence,
            "difference": np.nan_to_num(test["difference"]).tolist()}


def _illuminant_finding(measured, profile, n_permutations, seed):
    """Two tests of the as-shot neutrals against the profile's illuminant model, Bonferroni-
    combined: the energy test (any difference of distributions) and a parametric-bootstrap
    likelihood test (neutrals where the model has little density, e.g. an off-locus lamp type)."""
    from .. import illuminants as _illuminants

    points = measures.neutral_chromaticities(measured)
    if len(points) < 3:
        return {"cause": "illuminant_distribution", "score": 0.0, "p": 1.0, "magnitude": 0.0,
                "statistic": STATISTICS["illuminant_distribution"],
                "evidence": f"only {len(points)} files carry an as-shot neutral: not tested", "difference": []}
    model = profile.illuminants
    reference = gain.illuminant_samples(model, 200, seed)
    energy = significance.energy_permutation(points, reference, n_permutations=n_permutations, seed=seed)
    likelihood = significance.likelihood_bootstrap(
        points, lambda x: _illuminants.mixture_log_likelihood(model, x),
        lambda m, s: gain.illuminant_samples(model, m, s + 1), n_boot=n_permutations, seed=seed)
    p = min(1.0, 2 * min(energy["p"], likelihood["p"]))
    return {"cause": "illuminant_distribution", "score": max(energy["score"], likelihood["score"]), "p": p,
            "magnitude": energy["energy"], "statistic": STATISTICS["illuminant_distribution"],
            "evidence": f"energy distance {energy['energy']:.4f} between {len(points)} as-shot neutrals and "
                        f"200 profile samples (permutation p = {energy['p']:.4g}); mean log density under the "
                        f"profile {likelihood['observed']:.2f} (bootstrap p = {likelihood['p']:.4g})",
            "difference": []}


def _defect_finding(measured, simulated):
    shape = measured[0]["shape"]
    found = significance.consistent_outliers([f["outliers"] for f in measured], shape)
    control = significance.consistent_outliers([f["outliers"] for f in simulated], shape)
    excess = found["count"] - control["count"]
    p = found["p"] if excess > 0 else 1.0
    return {"cause": "defective_pixels", "score": found["score"] if excess > 0 else 0.0, "p": p,
            "magnitude": float(max(excess, 0)), "statistic": STATISTICS["defective_pixels"],
            "evidence": f"{found['count']} pixels are outliers in many measured files (chance level "
                        f"{found['expected']:.3g}), {control['count']} in simulated files", "difference": []}


def diagnose(profile, measured, *, scenes=None, n_simulated: int | None = None, seed: int = 0,
             alpha: float = 0.01, folds: int = 3, n_permutations: int = 2000, progress=None) -> dict:
    """Compare measured DNGs with the profile's simulation; name, fit and validate causes.

    **Arguments:**
    - `profile`: the `SensorProfile` under audit.
    - `measured`: DNG paths, or in-memory (mosaic (H, W) uint16, DngInfo) pairs; all one size.
    - `scenes`: (N, H, W, 3) sRGB images in [0, 1], or a folder of images, to simulate from;
      default: built-in dead-leaves scenes (`g2r_jax.audit.scenes`).
    - `n_simulated`: number of simulated files (default: as many as measured, at least 24).
    - `seed`: everything random (scenes, simulation, permutations, folds) derives from it.
    - `alpha`: family-wise error rate over all tests (Bonferroni over the statistics, maxT
      within each).
    - `folds`: cross-validation folds for the held-out gain.

    **Returns:** the report dict (REPORT.json's content): `findings` (one per tested statistic,
    significant first, by score), `unexplained`, `extended_profile` (the SensorProfile with every
    kept extension, under key "profile" - not JSON; `report.to_json` drops it) and run details.
    Raises DngError naming a file that cannot be used.
    """
    started = time.perf_counter()
    say = progress or (lambda message: None)
    files = loading.load_measured(measured)
    shapes = {m.shape for m, _ in files}
    if len(shapes) > 1:
        from ..io.dng_info import DngError
        raise DngError(files[0][1].path, f"measured files differ in size {sorted(shapes)}; audit one size at a time")
    height, width = files[0][0].shape
    n_sim = n_simulated or max(24, len(files))
    if scenes is None:
        scene_images = scene_set(n_sim, seed + 7919, height, width)
    elif isinstance(scenes, np.ndarray):
        scene_images = scenes
    else:
        scene_images = loading.load_scenes(scenes, n_sim, height, width)
    say(f"statistics of {len(files)} measured files")
    measured_stats = [stats.file_statistics(m, info, profile) for m, info in files]

    def simulate_stats(p, cause="all"):
        sim = simulate.simulate(p, scene_images, seed + 104729)
        return [stats.file_statistics(m, info, profile, with_outliers=cause in ("all", "defective_pixels"))
                for m, info in sim]

    say(f"simulating {len(scene_images)} files")
    simulated_stats = simulate_stats(profile)
    timing = {"statistics_s": time.perf_counter() - started}

    tests = len(_MEAN_TESTS) + 3
    threshold = alpha / tests

    def test_all(causes, sim_stats, current):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            out = [_mean_finding(c, measured_stats, sim_stats, current, n_permutations, seed)
                   for c in causes if c in _MEAN_TESTS + ("noise_correlation",)]
            if "illuminant_distribution" in causes:
                out.append(_illuminant_finding(measured_stats, current, n_permutations, seed))
            if "defective_pixels" in causes:
                out.append(_defect_finding(measured_stats, sim_stats))
        for f in out:
            f["significant"] = bool(f["p"] < threshold and f["magnitude"] >= TOLERANCE[f["cause"]])
            f["params"], f["gain"] = {}, None
        return sorted(out, key=lambda f: (not f["significant"], -f["score"]))

    # Explain away: take the strongest significant difference, validate its extension on held-out
    # files, and if kept re-simulate with it and re-test the rest (a difference that another
    # cause's extension reproduces is not a finding of its own).
    extended, current_stats, unexplained, done = profile, simulated_stats, [], []
    remaining = list(CAUSES) + ["noise_correlation"]
    while remaining:
        results = test_all(remaining, current_stats, extended)
        top = results[0]
        if not top["significant"]:
            done.extend(results)
            break
        remaining.remove(top["cause"])
        if top["cause"] == "noise_correlation":
            unexplained.append({"statistic": top["statistic"], "candidate": None, "score": top["score"],
                                "evidence": top["evidence"]})
            done.append(dict(top, cause=UNEXPLAINED, kept=False))
            continue
        say(f"cross-validating the {top['cause']} extension")
        top["gain"] = gain.cross_validate(top["cause"], measured_stats, current_stats, extended, simulate_stats,
                                          folds=min(folds, len(files)), seed=seed)
        if top["gain"]["after"] < top["gain"]["before"]:
            top["params"] = extensions.fit(top["cause"], measured_stats, current_stats, extended, seed=seed)
            top["kept"] = True
            extended = extensions.apply(extended, top["cause"], top["params"])
            current_stats = simulate_stats(extended)
            done.append(top)
        else:
            top["kept"] = False
            unexplained.append({"statistic": top["statistic"], "candidate": top["cause"], "score": top["score"],
                                "evidence": top["evidence"] + "; the candidate's extension does not help on held-out files"})
            done.append(dict(top, cause=UNEXPLAINED, candidate=top["cause"]))
    findings = [f for f in done if f["cause"] != "noise_correlation"]
    findings.sort(key=lambda f: (not f["significant"], -f["score"]))
    timing["total_s"] = time.perf_counter() - started
    return {
        "findings": findings, "unexplained": unexplained,
        "vocabulary": list(CAUSES), "alpha": alpha, "tests": tests, "threshold_p": threshold,
        "n_measured": len(files), "n_simulated": len(scene_images), "seed": seed,
        "size": [height, width], "timing": timing, "profile": extended,
    }
