"""`diagnose`: measured DNGs + a profile -> findings (cause, significance, fitted extension,
held-out gain) and an extended profile. Steps follow issue 3: statistics on measured and
simulated files, a test per statistic, a cause per significant difference, an extension fitted
on fit splits and kept only if it lowers the held-out discrepancy.
"""

from __future__ import annotations

import time

import numpy as np

from . import gain, loading, simulate, stats
from .causes import REGISTRY
from .scenes import scene_set
from .vocabulary import CAUSES, UNEXPLAINED


def diagnose(profile, measured=None, *, scenes=None, n_simulated: int | None = None, seed: int = 0,
             alpha: float = 0.01, folds: int = 3, n_permutations: int = 2000, progress=None,
             causes=None, on_error=None, charts=None) -> dict:
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
    - `causes`: the causes to test (`Cause` instances); default: the registry `causes.REGISTRY`.
    - `charts`: measured colour charts (a chart CSV path or a `charts.ChartSet`), the evidence of
      the causes with `evidence = "charts"` (`colour_matrix`); `measured` may then be None.

    **Returns:** the report dict (REPORT.json's content): `findings` (one per tested statistic,
    significant first, by score), `unexplained`, `extended_profile` (the SensorProfile with every
    kept extension, under key "profile" - not JSON; `report.to_json` drops it) and run details.
    Raises DngError naming a file that cannot be used; with `on_error`, such a file is reported
    to `on_error(line)` and left out instead (DngError only when no usable file is left).
    """
    started = time.perf_counter()
    say = progress or (lambda message: None)
    registry = tuple(REGISTRY if causes is None else causes)
    chart_causes = [c for c in registry if getattr(c, "evidence", "files") == "charts"]
    registry = tuple(c for c in registry if c not in chart_causes) if measured is not None else ()
    tests = len(registry) + (len(chart_causes) if charts is not None else 0)
    chart_report = _explain_with_charts(chart_causes, profile, charts, alpha / max(tests, 1), folds, n_permutations,
                                        seed, say) if charts is not None else None
    if measured is None:
        if chart_report is None:
            raise ValueError("nothing to audit: give measured DNG files, charts, or both")
        chart_report.update(alpha=alpha, tests=tests, threshold_p=alpha / max(tests, 1), seed=seed,
                            timing={"total_s": time.perf_counter() - started})
        return chart_report
    by_name = {c.name: c for c in registry}
    files = loading.load_measured(measured, on_error=on_error)
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
        return [stats.file_statistics(m, info, profile, 
                                     with_outliers=cause == "all" or by_name[cause].needs_outliers)
                for m, info in sim]

    say(f"simulating {len(scene_images)} files")
    simulated_stats = simulate_stats(profile)
    timing = {"statistics_s": time.perf_counter() - started}

    threshold = alpha / tests

    def test_all(causes, sim_stats, current):
        out = []
        for cause in causes:
            finding = cause.test(measured_stats, sim_stats, current, n_permutations=n_permutations, seed=seed)
            finding["significant"] = cause.is_significant(finding, threshold)
            finding["params"], finding["gain"] = {}, None
            out.append(finding)
        return sorted(out, key=lambda f: (not f["significant"], -f["score"]))

    # Explain away: take the strongest significant difference, validate its extension on held-out
    # files, and if kept re-simulate with it and re-test the rest (a difference that another
    # cause's extension reproduces is not a finding of its own).
    extended, current_stats, unexplained, done = profile, simulated_stats, [], []
    if chart_report is not None:   # colour first: the sensor causes are then tested against it
        extended, unexplained, done = chart_report["profile"], chart_report["unexplained"], chart_report["findings"]
        current_stats = simulate_stats(extended) if extended is not profile else simulated_stats
    remaining = list(registry)
    while remaining:
        results = test_all(remaining, current_stats, extended)
        top = results[0]
        if not top["significant"]:
            done.extend(results)
            break
        cause = next(c for c in remaining if c.name == top["cause"])
        remaining.remove(cause)
        if not cause.extensible:
            unexplained.append({"statistic": top["statistic"], "candidate": None, "score": top["score"],
                                "evidence": top["evidence"]})
            done.append(dict(top, cause=UNEXPLAINED, kept=False))
            continue
        say(f"cross-validating the {cause.name} extension")
        top["gain"] = gain.cross_validate(cause, measured_stats, current_stats, extended, simulate_stats,
                                          folds=min(folds, len(files)), seed=seed)
        if top["gain"]["after"] < top["gain"]["before"]:
            top["params"] = cause.fit(measured_stats, current_stats, extended, seed=seed)
            top["kept"] = True
            extended = cause.apply(extended, top["params"])
            current_stats = simulate_stats(extended)
            done.append(top)
        else:
            top["kept"] = False
            unexplained.append({"statistic": top["statistic"], "candidate": cause.name, "score": top["score"],
                                "evidence": top["evidence"] + "; the candidate's extension does not help on held-out files"})
            done.append(dict(top, cause=UNEXPLAINED, candidate=cause.name))
    # a statistic without an extension is a finding only when significant (as `unexplained`)
    by_name.update({c.name: c for c in chart_causes})
    findings = [f for f in done if f["cause"] == UNEXPLAINED or by_name[f["cause"]].extensible]
    findings.sort(key=lambda f: (not f["significant"], -f["score"]))
    timing["total_s"] = time.perf_counter() - started
    return {
        "findings": findings, "unexplained": unexplained,
        "vocabulary": list(CAUSES), "alpha": alpha, "tests": tests, "threshold_p": threshold,
        "n_measured": len(files), "n_simulated": len(scene_images), "seed": seed,
        **({"n_charts": chart_report["n_charts"], "charts": chart_report["charts"]} if chart_report else {}),
        "size": [height, width], "timing": timing, "profile": extended,
    }


def _explain_with_charts(chart_causes, profile, charts, threshold, folds, n_permutations, seed, say) -> dict:
    """The causes whose evidence is measured charts: test each, cross-validate the strongest
    significant one's extension over chart images and keep it if the held-out discrepancy drops
    (the same order as for files). Returns a partial report (findings, unexplained, profile)."""
    from ..charts import ChartSet, read_charts

    charts = charts if isinstance(charts, ChartSet) else read_charts(charts)
    say(f"testing {len(charts)} measured charts")
    extended, unexplained, done, remaining = profile, [], [], list(chart_causes)
    while remaining:
        results = []
        for cause in remaining:
            finding = cause.test(charts, None, extended, n_permutations=n_permutations, seed=seed)
            finding.update(significant=cause.is_significant(finding, threshold), params={}, gain=None)
            results.append(finding)
        results.sort(key=lambda f: (not f["significant"], -f["score"]))
        top = results[0]
        if not top["significant"]:
            done.extend(results)
            break
        cause = next(c for c in remaining if c.name == top["cause"])
        remaining.remove(cause)
        say(f"cross-validating the {cause.name} extension on chart images")
        top["gain"] = cause.cross_validate(charts, extended, folds=folds, seed=seed)
        top["kept"] = top["gain"]["after"] < top["gain"]["before"]
        if top["kept"]:
            top["params"] = cause.fit(charts, None, extended, seed=seed)
            extended = cause.apply(extended, top["params"])
            done.append(top)
        else:
            unexplained.append({"statistic": top["statistic"], "candidate": cause.name, "score": top["score"],
                                "evidence": top["evidence"] + "; the candidate's extension does not help on held-out images"})
            done.append(dict(top, cause=UNEXPLAINED, candidate=cause.name))
    return {"findings": sorted(done, key=lambda f: (not f["significant"], -f["score"])), "unexplained": unexplained,
            "vocabulary": list(CAUSES), "n_measured": 0, "n_charts": len(charts), "n_simulated": 0,
            "charts": charts.source, "profile": extended}
