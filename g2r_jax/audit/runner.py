"""`diagnose`: measured DNGs + a profile -> findings (cause, significance, fitted extension,
held-out gain) and an extended profile. Steps follow issue 3: statistics on measured and
simulated files, a test per statistic, a cause per significant difference, an extension fitted
on fit splits and kept only if it lowers the held-out discrepancy.

`diagnose` owns the order of the steps; each step is a plain function of the shared `Audit`
state (measure the files, plan the scenes, simulate, explain away one difference at a time,
assemble the report).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from g2r_jax.io.dng_info import DngError
from g2r_jax.measure.bursts import find_bursts
from g2r_jax.measure.photon_transfer import temporal_nlf
from g2r_jax.batch.conversion import file_key
from g2r_jax.audit import (black_evidence, bursts, content_report, evidence, gain, loading, scene_pedestal, simulate,
                           stats)
from g2r_jax.audit.causes import REGISTRY
from g2r_jax.audit.scenes import scene_set
from g2r_jax.audit.vocabulary import CAUSES, UNEXPLAINED


MIN_FILES_FOR_DEFECTS = 3   # a pixel is "consistently" defective only in several files of one size
SIMULATION_PIXELS = 240_000  # simulated files have the measured aspect and at most this many pixels
MEASURED_WORKERS = 2         # measured files whose statistics are computed at once (threads; memory ~0.3 GB each at 12 MP)


SCORE_CAP = 40.0   # |t| or z beyond this is certainty either way (p < 1e-300): rank by relevance


def rank(finding):
    """Sort key: significant first; then by score up to SCORE_CAP; among findings beyond it, by
    relevance (magnitude over the cause's tolerance: how many times the smallest difference
    worth reporting), so that two certain differences are ordered by how much they matter.
    The tolerances are set by hand, so relevance is known to a factor of about two: findings in
    the same factor-2 band (floor of log2) keep the registry order (noise before levels before
    optics; on the GoPro HERO6 frame noise_model 24.5 and white_level 25.7 share a band)."""
    relevance = finding.get("magnitude", 0.0) / max(finding.get("tolerance", 0.0), 1e-12) if finding.get("tolerance") else 0.0
    band = np.floor(np.log2(relevance)) if relevance > 0 else -np.inf
    name = finding.get("source") or finding["cause"]
    order = REGISTRY_ORDER.get(name, len(REGISTRY_ORDER))
    return (not finding["significant"], -min(finding["score"], SCORE_CAP), -band, order, -finding["score"])


REGISTRY_ORDER = {cause.name: k for k, cause in enumerate(REGISTRY)}


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


MAX_SIMULATED_SIZES = 4       # a folder of many sizes is simulated at its most common few (one program each)


def simulation_size(shape) -> tuple[int, int]:
    """(height, width) of the simulated files for measured files of `shape`: the same size up to
    SIMULATION_PIXELS, else scaled down with the same aspect (even sides)."""
    height, width = shape
    scale = min(1.0, float(np.sqrt(SIMULATION_PIXELS / (height * width))))
    return max(16, int(height * scale) // 2 * 2), max(16, int(width * scale) // 2 * 2)


def simulation_sizes(shapes, n_simulated: int) -> list[tuple[tuple[int, int], int]]:
    """[((height, width), count)]: the simulated set mirrors the measured set's mix of sizes.

    Some statistics depend on the file's size, not only on the sensor: on the demo camera the
    dark floor (0.5th percentile of 4x4 block means) averaged 1.9-3.5e-3 of the range in 120x180
    files, 0.1-0.4e-3 in 200x300 and -0.45e-3 in 400x600 (40 files each), so a mixed measured set
    against one simulated size raised false alarms (black_level in 5 of 20 clean mixed sets of
    120x180/160x240/200x300 before this). Each measured size maps to `simulation_size`; the
    MAX_SIMULATED_SIZES most common are kept (the others count towards the kept size nearest in
    area) and the `n_simulated` files are shared in proportion to the measured counts, the most
    common first (so one size gives exactly the old single-size set)."""
    counts = {}
    for shape in shapes:
        size = simulation_size(shape)
        counts[size] = counts.get(size, 0) + 1
    ranked = sorted(counts, key=lambda size: (-counts[size], size))
    kept = ranked[:MAX_SIMULATED_SIZES]
    weight = {size: counts[size] for size in kept}
    for size in ranked[MAX_SIMULATED_SIZES:]:
        nearest = min(kept, key=lambda k: abs(np.log(k[0] * k[1] / (size[0] * size[1]))))
        weight[nearest] += counts[size]
    total = sum(weight.values())
    shares = [max(1, int(round(n_simulated * weight[size] / total))) for size in kept]
    shares[0] += n_simulated - sum(shares)
    return [(size, count) for size, count in zip(kept, shares) if count > 0]


@dataclasses.dataclass
class Audit:
    """What the steps of one audit share (`diagnose` owns their order).

    Fixed once the measured files are read: the profile under audit, the causes tested on files
    (`registry`, by name in `by_name`), the measured items (`sources`, paths or in-memory pairs),
    whether outlier statistics are computed, the seed, the progress callback and the per-test
    threshold. Updated as the audit goes: the measured files' statistics (`measured_stats`), the
    independent scenes among them (`units`) and the bursts (`groups`), the scenes simulated from
    (`scene_groups`, `scene_keys`) and the statistics of every profile simulated so far
    (`simulated_sets`); while explaining away, the extended profile, the simulated statistics it
    gives (`current_stats`), the findings (`done`), the unexplained differences and the causes
    still to test (`remaining`)."""
    profile: object
    registry: tuple
    by_name: dict
    sources: list
    with_outliers: bool
    seed: int
    say: object
    n_items: int
    measured_stats: list = dataclasses.field(default_factory=list)
    units: list = dataclasses.field(default_factory=list)
    groups: list = dataclasses.field(default_factory=list)
    with_lens: bool = False
    scene_groups: list = dataclasses.field(default_factory=list)
    scene_keys: list = dataclasses.field(default_factory=list)
    simulated_sets: dict = dataclasses.field(default_factory=dict)
    threshold: float = 0.0
    black_files: list = dataclasses.field(default_factory=list)
    extended: object = None
    current_stats: list = dataclasses.field(default_factory=list)
    unexplained: list = dataclasses.field(default_factory=list)
    done: list = dataclasses.field(default_factory=list)
    remaining: list = dataclasses.field(default_factory=list)


def diagnose(profile, measured=None, *, scenes=None, n_simulated: int | None = None, seed: int = 0,
             alpha: float = 0.01, folds: int = 3, n_permutations: int = 2000, progress=None,
             causes=None, on_error=None, charts=None) -> dict:
    """Compare measured DNGs with the profile's simulation; name, fit and validate causes.

    **Arguments:**
    - `profile`: the `SensorProfile` under audit.
    - `measured`: DNG paths, or in-memory (mosaic (H, W) uint16, DngInfo) pairs; any sizes
      (simulated files take the commonest size, scaled to at most `SIMULATION_PIXELS`).
    - `scenes`: (N, H, W, 3) sRGB images in [0, 1], or a folder of images, to simulate from;
      default: built-in dead-leaves scenes (`g2r_jax.audit.scenes`).
    - `n_simulated`: number of simulated files (default: as many as the measured scenes, at least 24).
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
    Files of several sizes are audited together.
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
        return _charts_only(chart_report, profile, alpha, tests, seed, started)
    items = list(measured)
    if not items:
        raise ValueError("no measured files to audit")
    items = loading.check_measured(items, on_error=on_error)
    audit = Audit(profile=profile, registry=registry, by_name={c.name: c for c in registry}, sources=items,
                  with_outliers=len(items) >= MIN_FILES_FOR_DEFECTS, seed=seed, say=say, n_items=len(items))
    say(f"statistics of {len(items)} measured files")
    measure_files(audit, on_error)
    sizes = plan_scenes(audit, scenes, n_simulated)
    say(f"simulating {sum(count for _, count in sizes)} files")
    simulated_stats = simulate_stats(audit, profile)
    timing = {"statistics_s": time.perf_counter() - started}
    audit.threshold = alpha / tests
    audit.black_files = [f for f in audit.measured_stats if f.get("black") is not None]
    start_explaining(audit, chart_report, simulated_stats)
    while explain_next(audit, folds=folds, n_permutations=n_permutations):
        pass
    findings = final_findings(audit, chart_causes, simulated_stats)
    timing["total_s"] = time.perf_counter() - started
    return assemble_report(audit, findings, chart_report, sizes, alpha=alpha, tests=tests, timing=timing,
                           simulated_stats=simulated_stats)


def _charts_only(chart_report, profile, alpha, tests, seed, started) -> dict:
    """The report of an audit of measured charts alone."""
    if chart_report is None:
        raise ValueError("nothing to audit: give measured DNG files, charts, or both")
    chart_report.update(alpha=alpha, tests=tests, threshold_p=alpha / max(tests, 1), seed=seed,
                        profile_name=str(getattr(profile.info, "name", "") or ""),
                        timing={"total_s": time.perf_counter() - started})
    return chart_report


# ----------------------------------------------------------------------------- measured files

def statistics_of(audit: Audit, index: int, item, pedestal_dn=None):
    """The statistics of measured item `index` (a DngError instead when it cannot be read),
    measured from the profile's black or from `pedestal_dn` (DN above the tag) when given. One
    file in memory per worker: statistics are small, 12-MP mosaics are not."""
    try:
        (mosaic, info), = loading.load_measured([item])
    except DngError as error:
        return error
    profile = audit.profile
    found = stats.file_statistics(mosaic, info, profile, with_outliers=audit.with_outliers, seed=audit.seed + index,
                                  nlf_tiles=evidence.tiles_per_half(audit.n_items), pedestal_dn=pedestal_dn)
    found["item"] = index
    found["content_thumbnail"] = content_report.thumbnail(mosaic, info)
    found["pedestal_dn"] = np.resize(np.asarray(profile.effects.black_pedestal if pedestal_dn is None
                                                else pedestal_dn, np.float64), 4)   # the black it is measured from
    return found


def measure_files(audit: Audit, on_error) -> None:
    """Statistics of every measured file (unreadable ones to `on_error`, or raised), measured
    again from the black that scene-independent evidence shows where it differs from the
    profile's, and the bursts' temporal noise."""
    measured_stats = []
    # numpy releases the GIL in the large array operations, so files overlap on several cores
    with ThreadPoolExecutor(max(1, min(MEASURED_WORKERS, len(audit.sources), _cores()))) as pool:
        for result in pool.map(lambda pair: statistics_of(audit, *pair), enumerate(audit.sources)):
            if isinstance(result, DngError):
                if on_error is None:
                    raise result
                on_error(str(result))
                continue
            measured_stats.append(result)
    if not measured_stats:
        raise DngError(loading.folder_of(audit.sources), "no usable measured DNG files")
    audit.measured_stats = measured_stats
    pedestal = measured_black(measured_stats, audit.profile)
    if pedestal is not None:   # scene-independent evidence of another black: measure from it
        audit.say("black level differs from the profile's: statistics measured from the measured black")
        measure_again(audit, pedestal)
    else:
        with_bursts(audit, None)
    audit.with_lens = lens_shading_in(audit.measured_stats)


def measure_again(audit: Audit, black_dn) -> None:
    """The measured files' statistics measured from another black (DN above the tag), bursts included."""
    files = audit.measured_stats
    with ThreadPoolExecutor(max(1, min(MEASURED_WORKERS, len(audit.sources), _cores()))) as pool:
        audit.measured_stats = list(pool.map(
            lambda f: statistics_of(audit, f["item"], audit.sources[f["item"]], black_dn), files))
    with_bursts(audit, black_dn)


def with_bursts(audit: Audit, black_dn) -> None:
    """The independent scenes and bursts of the measured files; each burst's first frame carries
    its temporal noise, measured from `black_dn` (the profile's pedestal when None)."""
    files = audit.measured_stats
    audit.units, audit.groups = independent_files(files)
    for group in audit.groups:
        audit.say(f"photon transfer over a burst of {len(group)} frames")
        first = files[group[0]]
        first["temporal"] = burst_noise([audit.sources[files[i]["item"]] for i in group], first, audit.profile, black_dn)


# ----------------------------------------------------------------------------- simulation

def plan_scenes(audit: Audit, scenes, n_simulated) -> list:
    """The scenes the simulated files are made from (`audit.scene_groups`, with g2r-convert's
    keys for a folder of scene files) mirroring the measured sizes; returns [((h, w), count)]."""
    shapes = [f["shape"] for f in (audit.units or audit.measured_stats)]
    n_sim = n_simulated or max(24, len(audit.units) or len(audit.measured_stats))   # scenes: dark frames and bursts are not
    sizes = simulation_sizes(shapes, n_sim)
    seed = audit.seed
    if scenes is None:
        audit.scene_groups = [scene_set(count, seed + 7919 + 97 * k, h, w) for k, ((h, w), count) in enumerate(sizes)]
        audit.scene_keys = [None] * len(audit.scene_groups)
    elif isinstance(scenes, np.ndarray):
        audit.scene_groups, audit.scene_keys = [scenes], [None]
    else:
        # scene files are simulated with g2r-convert's key for (seed, file name): the audit's
        # simulated file of a scene is then the file `g2r-convert --seed SEED` writes for it
        loaded, names = loading.load_scenes(scenes, n_sim, *sizes[0][0], with_names=True)
        keys, seen = [], {}
        for name in names:   # a folder of fewer scenes than files is cycled: a repeat gets the next seed's key
            keys.append(file_key(seed + seen.get(name, 0), name))
            seen[name] = seen.get(name, 0) + 1
        audit.scene_groups, audit.scene_keys = [loaded], [keys]
    return [(tuple(int(v) for v in group.shape[1:3]), len(group)) for group in audit.scene_groups]


def simulate_stats(audit: Audit, profile, cause: str = "all") -> list:
    """Statistics of the files `profile` simulates from the audit's scenes (a profile simulated
    before, e.g. the same extension fitted again, is not simulated twice)."""
    outliers = audit.with_outliers and (cause == "all" or audit.by_name[cause].needs_outliers)
    key = simulate.profile_key(profile)
    cached = audit.simulated_sets.get(key)
    if cached is not None and (cached[0] or not outliers):
        return cached[1]
    seed = audit.seed
    sim = [file for k, group in enumerate(audit.scene_groups)
           for file in simulate.simulate(profile, group, seed + 104729 + 97 * k, keys=audit.scene_keys[k],
                                         lens_shading=audit.with_lens)]
    with ThreadPoolExecutor(max(1, min(MEASURED_WORKERS, _cores()))) as pool:
        result = list(pool.map(lambda i: stats.file_statistics(*sim[i], profile, seed=seed + 7 * i,
                                                               with_outliers=outliers), range(len(sim))))
    for f, (mosaic, info) in zip(result, sim):
        f["content_thumbnail"] = content_report.thumbnail(mosaic, info)
    audit.simulated_sets[key] = (outliers, result)
    return result


# ----------------------------------------------------------------------------- explaining away

def evidence_of(audit: Audit, cause) -> list:
    """The measured files a cause is tested on: for the black level those with black-level
    evidence (dark frames, optical-black pixels; all files when none has any, to say so), so
    that its cross-validation folds hold evidence; for the others the independent scenes
    (`independent_files`)."""
    return (audit.black_files or audit.measured_stats) if cause.name == "black_level" else audit.units


def test_all(audit: Audit, causes, n_permutations: int) -> list:
    """Every cause in `causes` tested against the current profile's simulation, ranked (`rank`)."""
    out = []
    for cause in causes:
        files = evidence_of(audit, cause)
        if not files:
            continue
        finding = cause.test(files, audit.current_stats, audit.extended, n_permutations=n_permutations,
                             seed=audit.seed)
        finding["significant"] = cause.is_significant(finding, audit.threshold)
        finding["tolerance"] = cause.tolerance
        finding["params"], finding["gain"] = {}, None
        out.append(finding)
    return sorted(out, key=rank)


def start_explaining(audit: Audit, chart_report, simulated_stats) -> None:
    """The state explaining away starts from: the profile (extended by the charts' findings
    when there are any: the sensor causes are then tested against it) and all file causes."""
    audit.extended, audit.current_stats = audit.profile, simulated_stats
    if chart_report is not None:   # colour first
        audit.extended, audit.unexplained, audit.done = (chart_report["profile"], chart_report["unexplained"],
                                                         chart_report["findings"])
        if audit.extended is not audit.profile:
            audit.current_stats = simulate_stats(audit, audit.extended)
    audit.remaining = list(audit.registry)


def explain_next(audit: Audit, *, folds: int, n_permutations: int) -> bool:
    """One round of explaining away: test the remaining causes, take the strongest significant
    difference, validate its extension on held-out files, and if kept re-simulate with it (a
    difference that another cause's extension reproduces is not a finding of its own). A noise
    or exposure difference is first weighed against a black pedestal (`scene_pedestal`).
    Returns False when nothing significant is left."""
    results = test_all(audit, audit.remaining, n_permutations)
    if not results:
        return False
    top = results[0]
    if not top["significant"]:
        audit.done.extend(results)
        return False
    cause = next(c for c in audit.remaining if c.name == top["cause"])
    audit.remaining.remove(cause)
    if not cause.extensible:
        audit.unexplained.append({"statistic": top["statistic"], "candidate": None, "score": top["score"],
                                  "evidence": top["evidence"]})
        audit.done.append(dict(top, cause=UNEXPLAINED, kept=False, source=cause.name))
        return True
    audit.say(f"cross-validating the {cause.name} extension")
    files = evidence_of(audit, cause)
    top["gain"] = gain.cross_validate(cause, files, audit.current_stats, audit.extended,
                                      functools.partial(simulate_stats, audit), folds=min(folds, len(files)),
                                      seed=audit.seed)
    rival = pedestal_rival(audit, cause, top, files, folds)
    if rival is not None and rival["verdict"] == "black_level":
        keep_pedestal(audit, cause, top, rival)
    elif rival is not None:
        record_undecided(audit, cause, top, rival)
    else:
        keep_or_refuse(audit, cause, top, files)
    return True


def pedestal_rival(audit: Audit, cause, top, files, folds: int):
    """`scene_pedestal.weigh` for a noise or exposure finding of a set without black-level
    evidence while black_level is still to be tested; None otherwise, and None when the scenes'
    darkest values or the low end of the noise curve rule the pedestal out (the words go to
    `top["pedestal_ruled_out"]`: the finding stands)."""
    if cause.name not in PEDESTAL_RIVALS or audit.black_files or "black_level" not in {c.name for c in audit.remaining}:
        return None
    rival = scene_pedestal.weigh(top, files, audit.current_stats, audit.extended, folds=folds, seed=audit.seed)
    if rival is not None and rival["verdict"] == "ruled_out":
        audit.say(f"a black pedestal does not explain the {cause.name} difference: {rival['evidence']}")
        top["pedestal_ruled_out"] = rival["evidence"]
        return None
    return rival


def keep_pedestal(audit: Audit, cause, top, rival) -> None:
    """A pedestal explains the difference better: keep it, measure the files from it, test the
    rest again (`cause` goes back to the causes still to test)."""
    audit.say(f"a black pedestal of {rival['pedestal_dn']:.1f} DN explains the {cause.name} difference better")
    black = audit.by_name["black_level"]
    audit.remaining.remove(black)
    audit.remaining.append(cause)
    audit.done.append(pedestal_finding(black, top, rival, audit.extended))
    audit.extended = black.apply(audit.extended, audit.done[-1]["params"])
    measure_again(audit, np.full(4, rival["pedestal_dn"]))
    audit.current_stats = simulate_stats(audit, audit.extended)


def record_undecided(audit: Audit, cause, top, rival) -> None:
    """The data cannot tell a black pedestal (`rival`) from `cause`: name neither, say what would decide."""
    decide = scene_pedestal.DECIDES
    audit.say(f"the {cause.name} difference could as well be a black pedestal: not fitted")
    words = f"{top['evidence']}; or {rival['evidence']}: the two cannot be told apart, {decide}"
    audit.unexplained.append({"statistic": top["statistic"], "candidate": cause.name, "alternative": "black_level",
                              "score": top["score"], "evidence": words, "decide_with": decide})
    audit.done.append(dict(top, cause=UNEXPLAINED, candidate=cause.name, source=cause.name, kept=False,
                           alternative="black_level", decide_with=decide, evidence=words, pedestal=rival))


def keep_or_refuse(audit: Audit, cause, top, files) -> None:
    """Keep `cause`'s extension when it lowered the held-out discrepancy (re-simulating with it),
    else record the difference as unexplained."""
    if top["gain"]["after"] < top["gain"]["before"]:
        top["params"] = cause.fit(files, audit.current_stats, audit.extended, seed=audit.seed)
        top["kept"] = True
        audit.extended = cause.apply(audit.extended, top["params"])
        audit.current_stats = simulate_stats(audit, audit.extended)
        audit.done.append(top)
        return
    top["kept"] = False
    audit.unexplained.append({"statistic": top["statistic"], "candidate": cause.name, "score": top["score"],
                              "evidence": top["evidence"] + "; the candidate's extension does not help on held-out files"})
    audit.done.append(dict(top, cause=UNEXPLAINED, candidate=cause.name, source=cause.name))


# ----------------------------------------------------------------------------- the report

def final_findings(audit: Audit, chart_causes, simulated_stats) -> list:
    """The findings in rank order, each significant one with the plot that makes its case (for
    the HTML report); a statistic without an extension is a finding only when significant (as
    `unexplained`)."""
    known = dict(audit.by_name, **{c.name: c for c in chart_causes})   # plots below: file causes only
    findings = [f for f in audit.done if f["cause"] == UNEXPLAINED or known[f["cause"]].extensible]
    findings.sort(key=rank)
    for f in findings:
        cause = audit.by_name.get(f.get("source", f["cause"]))
        if f["significant"] and cause is not None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                f["plot"] = cause.plot(evidence_of(audit, cause), simulated_stats, audit.profile,
                                       audit.extended if f.get("kept") else None)
    return findings


def assemble_report(audit: Audit, findings, chart_report, sizes, *, alpha, tests, timing, simulated_stats) -> dict:
    """The report dict (REPORT.json's content, and the extended profile under "profile"); "content":
    the scenes' content statistics, measured against simulated (`content_report`, no verdict)."""
    measured_stats, units = audit.measured_stats, audit.units
    shapes = [f["shape"] for f in (units or measured_stats)]
    return {
        "findings": findings, "unexplained": audit.unexplained,
        "vocabulary": list(CAUSES), "alpha": alpha, "tests": tests, "threshold_p": audit.threshold,
        "score_cap": SCORE_CAP, "n_measured": len(measured_stats), "n_simulated": sum(count for _, count in sizes),
        "seed": audit.seed, "profile_name": str(getattr(audit.profile.info, "name", "") or ""),
        "measured_files": [Path(str(f.get("name") or "")).name for f in measured_stats],
        "n_dark_frames": sum(bool(f.get("dark_frame")) for f in measured_stats),
        "bursts": [[measured_stats[i]["name"] for i in group] for group in audit.groups],
        "n_independent": len(units), "lens_shading_simulated": bool(audit.with_lens),
        **({"n_charts": chart_report["n_charts"], "charts": chart_report["charts"]} if chart_report else {}),
        "size": [int(v) for v in shapes[0]], "sizes": sorted({tuple(int(v) for v in s) for s in shapes}),
        "simulated_size": list(sizes[0][0]), "simulated_sizes": [[h, w, count] for (h, w), count in sizes],
        "content": content_report.compare(units, simulated_stats),
        "timing": timing, "profile": audit.extended,
    }


PEDESTAL_RIVALS = ("noise_model", "exposure_distribution")   # findings a black pedestal also explains (scene_pedestal)


def pedestal_finding(black, top, rival, profile) -> dict:
    """The black_level finding of a pedestal inferred from the scenes (`scene_pedestal.weigh`),
    with the held-out gain of its noise discrepancy; `top` is the finding it explains."""
    pedestal = np.full(4, rival["pedestal_dn"])
    difference = pedestal - np.asarray(profile.effects.black_pedestal, np.float64)
    return {"cause": black.name, "significant": True, "score": top["score"], "p": top["p"],
            "magnitude": abs(rival["offset_fraction"]), "tolerance": black.tolerance,
            "statistic": ("the noise curve and brightness of the scenes, measured from a black above the tag "
                          "(no dark frames or optical-black pixels in the set)"),
            "evidence": f"{rival['evidence']}; it explains the {top['cause']} difference ({top['evidence']})",
            "difference": difference.tolist(), "difference_dn": difference.tolist(), "explains": top["cause"],
            "scene_evidence": True, "closed_form": True, "tested": True, "gain": rival["gain"], "kept": True,
            "params": {"black_pedestal_dn": pedestal.tolist(), "offset_fraction": rival["offset_fraction"],
                       "from": "scene statistics (noise curve; brightness checked)"}}


def measured_black(files, profile):
    """(4,) DN: the sensor's black above the tag per position from the files' scene-independent
    evidence (`black_evidence`), where it differs from the profile's pedestal by more than three
    standard errors and `causes.black_level.RESOLUTION_DN`; None otherwise (the profile's
    pedestal stands: the statistics measure from it)."""
    from g2r_jax.audit.causes.black_level import RESOLUTION_DN
    from g2r_jax.audit.causes.base import per_colour

    found = [f["black"] for f in files if f.get("black") is not None]
    if not found:
        return None
    mean, se, _ = black_evidence.pooled_offset(found)
    current = np.asarray(profile.effects.black_pedestal, np.float64)
    differs = np.isfinite(mean) & (np.abs(mean - current) > np.maximum(3 * se, RESOLUTION_DN))
    if not differs.any():
        return None
    return per_colour(profile, np.where(np.isfinite(mean), mean, current))


def independent_files(files):
    """(units, bursts): the measured files that are independent scenes (dark frames left out;
    a burst's frames count once, by its first frame, which carries the burst's temporal noise),
    and the bursts (index lists, `measure.bursts.find_bursts`). Frames of one scene share the scene's
    statistics, so counting them as files would make a test over files see the scene N times."""
    groups = find_bursts(files)
    later = {i for group in groups for i in group[1:]}
    units = [f for i, f in enumerate(files) if not f.get("dark_frame") and i not in later]
    return units, groups


def burst_noise(items, first, profile, pedestal_dn=None) -> dict:
    """The temporal noise (`measure.photon_transfer.temporal_nlf`) of the burst of `items` (paths or in-memory
    pairs), `first` the statistics of its first frame."""
    frames, info = [], None
    for item in items:
        (mosaic, info), = loading.load_measured([item])
        pedestal = np.asarray(profile.effects.black_pedestal if pedestal_dn is None else pedestal_dn, np.float64)
        frames.append(bursts.frame_planes(mosaic, info.black_level, info.white_level, pedestal))
    black = np.resize(np.asarray(info.black_level, np.float64).reshape(-1), 4)
    span = float(info.white_level) - black
    pedestal = np.resize(pedestal, 4) / span
    clip = np.where(np.isfinite(first["clip"]) & (first["clip"] < 1.0), first["clip"], 1.0 - pedestal) - 2.0 / span
    clip_low = -black / span - pedestal + 2.0 / span
    return temporal_nlf(np.stack(frames), pedestal=pedestal, clip=clip, clip_low=clip_low,
                               edges=evidence.nlf_edges())


def lens_shading_in(files) -> bool:
    """True when most measured files carry lens-shading opcodes (their raw is divided by the
    lens gain, as `g2r-convert --lens-shading` writes): the simulation then does the same."""
    carry = [bool(np.any(np.asarray(f.get("gain_map_shading", 0.0)) != 0)) for f in files]
    return sum(carry) > len(carry) / 2


def _explain_with_charts(chart_causes, profile, charts, threshold, folds, n_permutations, seed, say) -> dict:
    """The causes whose evidence is measured charts: test each, cross-validate the strongest
    significant one's extension over chart images and keep it if the held-out discrepancy drops
    (the same order as for files). Returns a partial report (findings, unexplained, profile)."""
    from g2r_jax.colour.charts import ChartSet, read_charts

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
        top["plot"] = cause.chart_plot(top)
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
