"""The audit report: REPORT.json (machine-readable), a stdout summary, and an HTML page for
people: per finding the plot that makes the case (matplotlib, when installed), its parameters
and its held-out gain as before/after numbers.

Plots: `noise_model` - measured noise level function with its 95 % intervals against the
profile's model (and the extended one), in DN^2 against % of range; `illuminant_distribution` -
measured as-shot neutrals against samples of the profile's illuminant model; every other cause -
its per-file statistic, measured files against simulated ones, per component, in the
statistic's user units (DN for the dark floor, % of range for the clipping level, corner gain
for shading).
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from g2r_jax.io.atomic import atomic_write_bytes
from g2r_jax.audit import content_report, wording
from g2r_jax.audit.causes.base import position_labels


def _plain(value):
    """JSON-ready copy: numpy scalars/arrays to Python, non-finite floats to None."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (np.floating, float)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.bool_,)):
        return bool(value)
    return value


FINDING_KEYS = ("cause", "significant", "score", "statistic", "evidence", "params", "gain", "p", "kept", "candidate",
                "sentence", "action", "p_words", "pedestal_ruled_out")


def to_json(report: dict) -> dict:
    """The REPORT.json document (the extended SensorProfile and plot data are left out)."""
    document = {k: v for k, v in report.items() if k not in ("profile", "plots")}
    findings = [dict(f, sentence=wording.sentence(f), action=wording.action(f, report), p_words=wording.p_words(f["p"]),
                     evidence=wording.clean(f["evidence"])) for f in report["findings"]]
    document["findings"] = [{k: f[k] for k in FINDING_KEYS if k in f} for f in findings]
    document["ranking"] = wording.RANKING.format(cap=report.get("score_cap", 40.0))
    return _plain(document)


def write_json(report: dict, path) -> None:
    text = json.dumps(to_json(report), indent=1, allow_nan=False)
    atomic_write_bytes(Path(path), (text + "\n").encode())


def gain_words(gain: dict | None, kept=None) -> str:
    """'held-out METRIC: before -> after (N % lower; on held-out files)' for people."""
    if not gain:
        return ""
    before, after = gain["before"], gain["after"]
    change = (after / before - 1) * 100 if before else 0.0
    where = {True: "on held-out files", "regions": "on held-out regions of the file",
             False: "in-sample (one file, no held-out part)"}.get(gain.get("heldout"), "")
    verdict = "" if kept is None else ("; kept" if kept else "; rejected")
    return f"{gain['metric']}: {before:.4g} -> {after:.4g} ({change:+.0f} %, {where}{verdict})"


def setting_words(report: dict) -> list:
    """Lines on what was compared: bursts (noise over time), dark frames (black level), lens shading."""
    lines = []
    for burst in report.get("bursts") or []:
        lines.append(f"{len(burst)} files are frames of one scene (a burst): its noise is measured over time, pixel "
                     "by pixel (photon transfer), and it counts as one scene in the other tests")
    if report.get("n_dark_frames"):
        lines.append(f"{report['n_dark_frames']} dark frame(s) found: they give the black level")
    return lines


def summary(report: dict) -> str:
    """A readable summary: per significant finding a plain sentence, what to do, the held-out
    gain; the technical evidence is in REPORT.json and the HTML page's details."""
    evidence = []
    if report.get("n_measured"):
        sizes = report.get("sizes") or [report["size"]]
        size_words = ", ".join(f"{h}x{w}" for h, w in sizes)
        simulated = "x".join(str(v) for v in report.get("simulated_size", report["size"]))
        evidence.append(f"{report['n_measured']} measured ({size_words}) vs {report['n_simulated']} simulated "
                        f"files ({simulated})")
    if report.get("n_charts"):
        evidence.append(f"{report['n_charts']} measured chart images")
    lines = [f"g2r-diagnose: {', '.join(evidence)}, family-wise alpha {report['alpha']}"]
    lines += [f"  {line}" for line in setting_words(report)]
    significant = [f for f in report["findings"] if f["significant"]]
    if not significant:
        lines.append("no significant difference between the measured files and the simulation")
    for k, f in enumerate(significant, 1):
        name = f["cause"] if f["cause"] != "unexplained" else f"unexplained ({f.get('candidate') or f.get('source')})"
        lines.append(f"{k}. {name}: {wording.sentence(f)}")
        lines.append(f"   what to do: {wording.action(f, report)}")
        if f.get("gain"):
            lines.append(f"   held-out {gain_words(f['gain'], f.get('kept'))}")
        lines.append(f"   ({wording.p_words(f['p'])}, score {f['score']:.1f}; details in the report)")
    if len(significant) > 1:
        lines.append(wording.RANKING.format(cap=report.get("score_cap", 40.0)))
    lines += content_report.lines(report.get("content"))
    lines.append(f"time {report['timing']['total_s']:.1f} s")
    return "\n".join(lines)


def _params_words(params: dict, limit: int = 8) -> str:
    def fmt(v):
        if isinstance(v, (list, tuple, np.ndarray)):
            flat = np.asarray(v, dtype=object).ravel().tolist() if not isinstance(v, np.ndarray) else v.ravel().tolist()
            try:
                flat = np.asarray(v, np.float64).ravel()
                text = ", ".join(f"{x:.4g}" for x in flat[:limit])
                return f"[{text}{', ...' if flat.size > limit else ''}]"
            except (TypeError, ValueError):
                return str(v)[:80]
        if isinstance(v, float):
            return f"{v:.4g}"
        return str(v)
    return "; ".join(f"{k} = {fmt(v)}" for k, v in params.items() if k != "hull_points")


# ----------------------------------------------------------------------------- plots


def _position_colours(labels) -> list:
    """A plot colour per CFA position: red, green (two shades), blue after the labels' colour."""
    if not labels:
        return ["tab:red", "tab:green", "tab:olive", "tab:blue"]
    greens = iter(["tab:green", "tab:olive", "darkgreen", "yellowgreen"])
    return [{"R": "tab:red", "B": "tab:blue"}.get(str(label)[:1]) or next(greens) for label in labels]


def _nlf_plot(ax, data):
    """Measured NLF (points with 95 % intervals, half A and B together) against the model(s)."""
    colours = _position_colours(data.get("labels"))
    f = data["files"][0]
    span = np.resize(np.asarray(f.get("span") or 1.0, np.float64), 4)
    for p in range(4):
        xs, ys, lo, hi, model = [], [], [], [], []
        for half in f["halves"].values():
            xs += half["signal"][p]
            ys += half["variance"][p]
            lo += half["lower"][p]
            hi += half["upper"][p]
            model += half["model"][p]
        x, y, lo, hi = (np.asarray(v, np.float64) for v in (xs, ys, lo, hi))
        ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
        scale = span[p] ** 2
        ax.errorbar(100 * x[ok], y[ok] * scale, yerr=[(y[ok] - lo[ok]) * scale, (hi[ok] - y[ok]) * scale],
                    fmt="o", ms=3, color=colours[p], label=f"measured, {(data.get('labels') or position_labels())[p]} "
                                                            "(95 % interval)")
    grid = np.geomspace(1e-4, 1.0, 100)
    for key, style, words in (("model_curve", "--", "profile's model"), ("extended_curve", "-", "extended profile")):
        if data.get(key) is not None:
            curve = np.asarray(data[key], np.float64)
            for p in range(4):
                ax.plot(100 * grid, curve[p] * span[p] ** 2, style, color=colours[p], lw=1,
                        label=words if p == 0 else None)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("signal (% of range above black)")
    ax.set_ylabel("noise variance (DN$^2$)")
    ax.set_title(f"noise level function of {Path(f.get('name') or 'file').name} (ISO {f['iso']:.0f})")
    ax.legend(fontsize=7)


def _strip_plot(ax, data):
    """Per component: measured files (red) and simulated files (grey), in the statistic's units."""
    m, s = np.asarray(data["measured"], np.float64), np.asarray(data["simulated"], np.float64)
    k = m.shape[1] if m.ndim == 2 else 0
    rng = np.random.default_rng(0)
    for j in range(k):
        sv = s[:, j][np.isfinite(s[:, j])] if s.size else np.zeros(0)
        mv = m[:, j][np.isfinite(m[:, j])]
        ax.scatter(j - 0.15 + 0.08 * rng.standard_normal(sv.size), sv, s=10, color="0.6",
                   label=data.get("simulated_label", "simulated files (profile)") if j == 0 else None)
        ax.scatter(np.full(mv.size, j + 0.15), mv, s=24, color="tab:red", marker="D",
                   label="measured files" if j == 0 else None)
    ax.set_xticks(range(k))
    ax.set_xticklabels(data.get("labels") or [str(j) for j in range(k)], fontsize=8)
    ax.set_ylabel(data.get("unit", "statistic"))
    ax.set_title(data.get("title", ""))
    ax.legend(fontsize=7)


def _neutral_plot(ax, data):
    m, s = np.asarray(data["measured"]), np.asarray(data["model"])
    ax.scatter(s[:, 0], s[:, 1], s=6, color="0.6", label="samples of the profile's illuminant model")
    if data.get("extended") is not None:
        e = np.asarray(data["extended"])
        ax.scatter(e[:, 0], e[:, 1], s=6, color="tab:blue", alpha=0.5, label="samples of the extended model")
    ax.scatter(m[:, 0], m[:, 1], s=24, color="tab:red", marker="D", label="measured as-shot neutrals")
    ax.set_xlabel("r/g of the as-shot neutral")
    ax.set_ylabel("b/g of the as-shot neutral")
    ax.set_title("neutrals against the illuminant model")
    ax.legend(fontsize=7)


def _patch_plot(ax, data):
    """Per chart patch: the profile's error and, when cross-validated, the refit's on held-out images."""
    before = np.asarray(data["before"], np.float64)
    x = np.arange(before.size)
    after = data.get("after")
    width = 0.4 if after is not None else 0.8
    ax.bar(x - (width / 2 if after is not None else 0), before, width, color="0.6", label="profile's colour model")
    if after is not None:
        ax.bar(x + width / 2, np.asarray(after, np.float64), width, color="tab:blue",
               label="refitted colour model, held-out images")
    ax.set_xticks(x)
    ax.set_xticklabels(data.get("labels") or [str(j + 1) for j in x], rotation=70, ha="right", fontsize=7)
    ax.set_ylabel(data.get("unit", "deg"), fontsize=8)
    ax.set_title(data.get("title", ""), fontsize=9)
    ax.legend(fontsize=7)


def _plot_finding(finding, path) -> bool:
    data = finding.get("plot")
    if not data:
        return False
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    try:
        {"nlf": _nlf_plot, "strip": _strip_plot, "neutrals": _neutral_plot, "patches": _patch_plot}[data["kind"]](ax, data)
        fig.tight_layout()
        atomic_write_bytes(Path(path), lambda handle: fig.savefig(handle, format="png", dpi=90))
    finally:
        plt.close(fig)
    return True


_STYLE = ("body{font-family:sans-serif;max-width:1000px;margin:1em auto;color:#222;line-height:1.35}"
          "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:3px 6px;font-size:13px;vertical-align:top}"
          ".finding{border:1px solid #ccc;border-radius:6px;padding:0.6em 1em;margin:1em 0}"
          ".status{font-size:14px;font-weight:normal;padding:1px 8px;border-radius:4px;margin-left:0.6em}"
          ".fixed{background:#dff0d8}.open{background:#f8e0c0}.summary{font-size:16px}"
          ".note{color:#555;font-size:13px}code{background:#f3f3f3;padding:0 3px}"
          ".yes{color:#b00;font-weight:bold}.gain{font-size:15px}")


def _names(names, limit: int = 4) -> str:
    names = [n for n in names if n]
    if not names:
        return ""
    shown = ", ".join(names[:limit])
    return f" ({shown}{f' and {len(names) - limit} more' if len(names) > limit else ''})"


def header_lines(report: dict) -> list:
    """The page's opening lines: what was compared with what, and where the outputs are."""
    lines = []
    if report.get("profile_name"):
        lines.append(f"Profile: {report['profile_name']}.")
    if report.get("n_measured"):
        sizes = ", ".join(f"{h} x {w}" for h, w in (report.get("sizes") or [report["size"]]))
        simulated = " x ".join(str(v) for v in report.get("simulated_size", report["size"]))
        lines.append(f"Measured: {report['n_measured']} DNG file(s){_names(report.get('measured_files') or [])} of "
                     f"{sizes} pixels, compared with {report['n_simulated']} files simulated from the profile "
                     f"({simulated} pixels).")
    if report.get("n_charts"):
        lines.append(f"Measured: {report['n_charts']} colour chart image(s).")
    lines += [line[0].upper() + line[1:] + "." for line in setting_words(report)]
    lines.append(f"Differences are reported at a family-wise error rate of {report['alpha']:g} (the chance that a "
                 "camera the profile describes exactly shows any finding).")
    return lines


def result_line(report: dict) -> str:
    """One sentence: how many differences, how many the extended profile fixes, where it is."""
    significant = [f for f in report["findings"] if f["significant"]]
    if not significant:
        return "No significant difference between the measured files and the simulation: the profile fits."
    kept = sum(bool(f.get("kept")) for f in significant)
    words = f"{len(significant)} significant difference(s): {kept} fixed by the extended profile"
    if kept and report.get("extended_profile"):
        words += (f" ({html.escape(report['extended_profile'])}; convert with "
                  f"<code>g2r-convert --profile {html.escape(report['extended_profile'])}</code>)")
    elif kept:
        words += " (rerun with <code>--extended-profile PATH</code> to save it)"
    if len(significant) - kept:
        words += f", {len(significant) - kept} not fixed (see below)"
    return words + "."


def _content_html(section) -> str:
    """The scenes' content statistics, measured against simulated (no verdict), as a table."""
    if not section:
        return ""
    fmt = lambda v: "-" if v is None else f"{v:.3g}"
    rows = "".join(f"<tr><td>{html.escape(content_report.WORDS.get(n, n))}</td><td>{fmt(section['measured'][n])}</td>"
                   f"<td>{fmt(section['simulated'][n])}</td></tr>" for n in section["names"])
    return (f"<h2>Scene content (not the camera)</h2><p class='note'>Medians over {section['n_measured']} measured and "
            f"{section['n_simulated']} simulated files, on 64 x 64 white-balanced camera-RGB thumbnails. What the "
            f"scenes hold, not a property of the sensor: not tested, no verdict.</p><table><tr><th>statistic</th>"
            f"<th>measured</th><th>simulated</th></tr>{rows}</table>")


def write_html(report: dict, folder) -> Path | None:
    """report.html in `folder`: what was compared, the result in one sentence and where the
    outputs are; then one numbered section per significant finding (plain title, what differs,
    what to do, the plot that makes the case as a PNG next to the page when matplotlib is
    installed, the held-out check as before/after numbers; statistic, evidence and fitted
    parameters in a collapsed details part); then a table of every test. Returns the page."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        import matplotlib  # noqa: F401
        can_plot = True
    except ImportError:
        can_plot = False
    sections = []
    for i, f in enumerate(report["findings"]):
        if not f["significant"]:
            continue
        image = ""
        name = f"finding_{i}_{f['cause']}.png"
        if can_plot and _plot_finding(f, folder / name):
            image = f'<p><img src="{name}" alt="plot for {html.escape(f["cause"])}" width="700"></p>'
        gain = ""
        if f.get("gain"):
            g = f["gain"]
            where = {True: "held-out files", "regions": "held-out regions of the file",
                     False: "in-sample (one file: no held-out part)"}.get(g.get("heldout"), "")
            verdict = "kept (in the extended profile)" if f.get("kept") else "rejected (no gain)"
            gain = (f"<table><tr><th>check of the fitted extension</th><th>before (profile)</th>"
                    f"<th>after (extended)</th><th>change</th><th>verdict</th></tr><tr><td>{html.escape(g['metric'])}, "
                    f"{where}</td><td>{g['before']:.4g}</td><td>{g['after']:.4g}</td>"
                    f"<td>{(g['after'] / g['before'] - 1) * 100 if g['before'] else 0:+.0f} %</td>"
                    f"<td>{verdict}</td></tr></table>")
        params = ""
        if f.get("params"):
            rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(_params_words({k: v}).split(' = ', 1)[-1])}</td></tr>"
                           for k, v in f["params"].items() if k != "hull_points")
            params = f"<table><tr><th>fitted parameter</th><th>value</th></tr>{rows}</table>"
        state = wording.status(f)
        sections.append(
            f"<div class='finding'><h2>{len(sections) + 1}. {html.escape(wording.title(f))}"
            f"<span class='status {'fixed' if f.get('kept') else 'open'}'>{html.escape(state)}</span></h2>"
            f"<p><b>{html.escape(wording.sentence(f))}</b></p>"
            f"<p>What to do: {html.escape(wording.action(f, report))}</p>{image}<p class='gain'>{gain}</p>"
            f"<details><summary>details (statistic, evidence, fitted parameters)</summary>"
            f"<p>{html.escape(wording.p_words(f['p']))}, score {f['score']:.1f}. "
            f"<i>{html.escape(f['statistic'])}</i></p><p>{html.escape(wording.clean(f['evidence']))}</p>{params}"
            f"</details></div>")
    ranking = ""
    if len(sections) > 1:
        ranking = f"<p class='note'>{html.escape(wording.RANKING.format(cap=report.get('score_cap', 40.0)))}</p>"
    rows = "".join(
        f"<tr><td>{html.escape(str(f['cause']))}</td><td class='{'yes' if f['significant'] else ''}'>"
        f"{'yes' if f['significant'] else 'no'}</td><td>{f['score']:.2f}</td><td>{html.escape(wording.p_words(f['p']))}</td>"
        f"<td>{html.escape(wording.clean(f['evidence']))}</td></tr>" for f in report["findings"])
    head = "".join(f"<p>{html.escape(line)}</p>" for line in header_lines(report))
    outputs = ""
    if report.get("report_path"):
        outputs = (f"<p class='note'>Written: this page ({html.escape(str(folder / 'report.html'))}), "
                   f"the machine-readable report {html.escape(str(report['report_path']))}"
                   + (f", the extended profile {html.escape(str(report['extended_profile']))}"
                      if report.get("extended_profile") else "") + ".</p>")
    page = folder / "report.html"
    atomic_write_bytes(page, (
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>g2r-diagnose report</title><style>{_STYLE}</style>"
        f"</head><body><h1>g2r-diagnose report</h1>{head}<p class='summary'><b>Result:</b> {result_line(report)}</p>"
        f"{outputs}{ranking}{''.join(sections)}"
        f"<details><summary>All tests (details)</summary><table><tr><th>cause</th><th>significant</th><th>score</th><th>p</th><th>evidence</th></tr>"
        f"{rows}</table></details>{_content_html(report.get('content'))}<p class='note'>time {report['timing']['total_s']:.1f} s</p></body></html>\n").encode())
    return page
