"""The colour check's result in words, tables and a plot: the rows side by side, the gap to real
training split into the profile's share and the CG content's, and what differs in the content
(the `document`, `sentences` and `markdown` of the check's `downstream.report.Report`)."""

from __future__ import annotations

import numpy as np

from g2r_jax.downstream.base.figures import save_figure
from g2r_jax.downstream.illuminant.experiment import ROWS, ExperimentResult


def decomposition(result: ExperimentResult, estimator: str) -> dict:
    """The gap between training on g2r_jax's RAW of the CG images as the product makes it
    ('fitted': lights and content model fitted) and on the real files ('real'), split along the
    controls (mean errors, degrees; absent rows give None): round trip (real_own_light - real),
    relighting (real_other_light - real_own_light), illuminant model (real_profile_light -
    real_other_light), profile = real_profile_light - real, content = fitted -
    real_profile_light; and what the content model gains, content_model = fitted_no_content -
    fitted."""
    mean = {r: result.summary(r, estimator)["mean"] for r in result.rows}
    get = mean.get

    def difference(a, b):
        return None if get(a) is None or get(b) is None else get(a) - get(b)

    return {"gap": difference("fitted", "real"), "round_trip": difference("real_own_light", "real"),
            "relighting": difference("real_other_light", "real_own_light"),
            "illuminant_model": difference("real_profile_light", "real_other_light"),
            "profile": difference("real_profile_light", "real"), "content": difference("fitted", "real_profile_light"),
            "other_content": difference("other_content", "real_profile_light"),
            "content_model": difference("fitted_no_content", "fitted"),
            "versus_upi": None if get("upi") is None or get("fitted") is None else 1 - get("fitted") / get("upi")}


def table(result: ExperimentResult) -> str:
    """Markdown table: one line per row, per estimator mean / median / best 25 % / worst 25 %
    (pooled over seeds) and the range of the seeds' means."""
    head = "| row | " + " | ".join(f"{e}: mean (seeds) | median | best 25 % | worst 25 %" for e in result.estimators) + " |"
    rule = "|---|" + "---|---|---|---|" * len(result.estimators)
    lines = [head, rule]
    for row in result.rows:
        cells = []
        for e in result.estimators:
            s = result.summary(row, e)
            spread = f" ({s['seed_min']:.2f}-{s['seed_max']:.2f})" if len(result.seeds) > 1 else ""
            cells.append(f"{s['mean']:.2f}{spread} | {s['median']:.2f} | {s['best25']:.2f} | {s['worst25']:.2f}")
        lines.append(f"| {ROWS[row]} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def seeds_apart(result: ExperimentResult, a: str, b: str, estimator: str):
    """True when every seed's mean error of row `a` lies on one side of every seed's of row `b`
    (a difference larger than the training noise the seeds show), False when their ranges
    overlap, None with fewer than two seeds (the training noise is not measured). An illuminant
    CNN trained twice on the same data can differ by degrees on a fold (docs validation
    illuminant_models, "How fine this benchmark can see"), so a difference is named only when
    the seeds agree on its sign."""
    if len(result.seeds) < 2:
        return None
    x, y = result.summary(a, estimator), result.summary(b, estimator)
    return bool(x["seed_max"] < y["seed_min"] or y["seed_max"] < x["seed_min"])


def sentence(result: ExperimentResult, estimator: str, content_rows=None) -> str:
    """One result sentence for the estimator: g2r_jax against UPI and real training, and where
    the gap lies; a difference whose seeds overlap is called within training noise
    (`seeds_apart`)."""
    mean = {r: result.summary(r, estimator)["mean"] for r in result.rows}
    parts = []
    ours_row = "fitted" if "fitted" in mean else "shipped" if "shipped" in mean else None
    if ours_row is None:
        return f"{estimator}: " + ", ".join(f"{ROWS[r]} {v:.2f} deg" for r, v in mean.items())
    ours = mean[ours_row]
    made = " as g2r-fit-profile makes it (lights and content model fitted)" if ours_row == "fitted" else ""
    parts.append(f"an estimator ({estimator}) trained on g2r_jax RAW of the CG images{made} errs {ours:.2f} deg "
                 f"on the real files")
    others = [f"{label} {mean[r]:.2f}" for r, label in (("upi", "UPI"), ("real", "trained on the real files"))
              if r in mean]
    if "upi" in mean and seeds_apart(result, ours_row, "upi", estimator) is False:
        others[0] += ", within training noise of g2r_jax"
    if others:
        parts[-1] += f" ({', '.join(others)})"
    if len(result.seeds) < 2:
        parts[-1] += "; one seed: the training noise is not measured"
    split = decomposition(result, estimator)
    if split["content_model"] is not None:
        noise = " (within training noise)" if seeds_apart(result, "fitted", "fitted_no_content", estimator) is False else ""
        gain = split["content_model"]
        parts.append(f"the content model {'lowers' if gain >= 0 else 'raises'} it by {abs(gain):.2f} deg "
                     f"(without it {mean['fitted_no_content']:.2f}){noise}")
    if split["gap"] is not None and split["profile"] is not None:
        noise = (" (within training noise)" if seeds_apart(result, "real_profile_light", "real", estimator) is False
                 else "")
        parts.append(f"of the {split['gap']:.2f} deg gap to real training, {split['profile']:.2f} is the profile "
                     f"(colour and lights){noise} and {split['content']:.2f} the CG content")
        measured = [r for r in content_rows or () if r.get("spread", True) and np.isfinite(r["excess"])]
        if measured and split["content"] > max(split["profile"], 0.0) and measured[0]["excess"] > 1:
            top = measured[0]
            parts.append(f"the CG content differs most from the real files in {top['description']}: "
                         f"{top['synthetic']:.3g} against {top['real']:.3g} ({top['distance']:+.1f} robust std)")
    augmented = augmentation_phrase(result, estimator)
    if augmented:
        parts.append(augmented)
    return "; ".join(parts) + "."


def augmentation_phrase(result: ExperimentResult, estimator: str) -> str:
    """What adding g2r_jax RAW to the real files is worth with this many of them ('' without the
    rows 'real' and 'real_plus_fitted'): real alone against real + g2r_jax, within training noise
    when the seeds overlap, and the recipes the training files chose."""
    if not {"real", "real_plus_fitted"} <= set(result.rows):
        return ""
    alone, added = (result.summary(r, estimator)["mean"] for r in ("real", "real_plus_fitted"))
    files = (f"{result.labelled} labelled files" if result.labelled else
             f"your {result.files} files (each test fold's estimator trains on the other folds')"
             if result.files else "your files")
    verb = "lowers" if added < alone else "raises" if added > alone else "leaves"
    noise = " (within training noise)" if seeds_apart(result, "real_plus_fitted", "real", estimator) is False else ""
    chosen = sorted(set(result.recipes.get(("real_plus_fitted", estimator), [])))
    recipe = f", recipe chosen on the training files: {', '.join(chosen)}" if chosen else ""
    return (f"with {files}, adding g2r_jax RAW {verb} its error from {alone:.2f} to {added:.2f} deg "
            f"({(added - alone) / alone:+.0%}){noise}{recipe}")


def content_table(rows) -> str:
    """Markdown table of `content.compare`: medians, distances in the real set's robust std and the
    ratio of the sets' spreads; a statistic without spread in the real files says so instead."""
    control = rows and "control" in rows[0]
    head = ("| statistic | CG set | real files | distance | spread, CG / real |"
            + (" real files made RAW again | its distance |" if control else ""))
    lines = [head, "|---|---|---|---|---|" + ("---|---|" if control else "")]
    for r in rows:
        measured = r.get("spread", True)
        distance = f"{r['distance']:+.1f}" if measured else "no spread in the real files"
        ratio = f"{r['spread_ratio']:.2f}x" if measured and np.isfinite(r.get("spread_ratio", np.nan)) else "-"
        line = f"| {r['description']} | {r['synthetic']:.3g} | {r['real']:.3g} | {distance} | {ratio} |"
        if control:
            line += f" {r['control']:.3g} | {r['control_distance']:+.1f} |" if measured else f" {r['control']:.3g} | - |"
        lines.append(line)
    return "\n".join(lines)


def plot(result: ExperimentResult, path) -> bool:
    """Bar chart of the mean error per row and estimator (PNG, written atomically); False when
    matplotlib is not installed."""
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 0.45 * len(result.rows) + 1.2))
    height = 0.8 / len(result.estimators)
    y = np.arange(len(result.rows))
    for k, e in enumerate(result.estimators):
        stats = [result.summary(r, e) for r in result.rows]
        means = [s["mean"] for s in stats]
        low = [max(s["mean"] - s["seed_min"], 0.0) for s in stats]
        high = [max(s["seed_max"] - s["mean"], 0.0) for s in stats]
        ax.barh(y + k * height, means, height, xerr=[low, high], label=e)
    ax.set_yticks(y + 0.4 - height / 2, [ROWS[r] for r in result.rows])
    ax.invert_yaxis()
    ax.set_xlabel("mean angular error on the real files (degrees)")
    ax.set_title(f"{result.camera}: illuminant estimators by training set")
    ax.legend()
    return save_figure(fig, path)
