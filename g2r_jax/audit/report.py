"""The audit report: REPORT.json (machine-readable), a stdout summary, and an HTML page with a
PNG plot for people (plots only when matplotlib is installed)."""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write_bytes


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


FINDING_KEYS = ("cause", "significant", "score", "statistic", "evidence", "params", "gain", "p", "kept", "candidate")


def to_json(report: dict) -> dict:
    """The REPORT.json document (the extended SensorProfile itself is left out)."""
    document = {k: v for k, v in report.items() if k != "profile"}
    document["findings"] = [{k: f[k] for k in FINDING_KEYS if k in f} for f in report["findings"]]
    return _plain(document)


def write_json(report: dict, path) -> None:

    text = json.dumps(to_json(report), indent=1, allow_nan=False)
    atomic_write_bytes(Path(path), (text + "\n").encode())


def summary(report: dict) -> str:
    """A readable summary: significant findings first, with their gain."""
    evidence = []
    if report.get("n_measured"):
        evidence.append(f"{report['n_measured']} measured vs {report['n_simulated']} simulated files "
                        f"({report['size'][0]}x{report['size'][1]})")
    if report.get("n_charts"):
        evidence.append(f"{report['n_charts']} measured chart images")
    lines = [f"g2r-diagnose: {', '.join(evidence)}, family-wise alpha {report['alpha']}"]
    significant = [f for f in report["findings"] if f["significant"]]
    if not significant:
        lines.append("no significant difference between the measured files and the simulation")
    for f in significant:
        lines.append(f"* {f['cause']}  (score {f['score']:.1f}, p {f['p']:.2g})")
        lines.append(f"    {f['evidence']}")
        if f.get("gain"):
            g = f["gain"]
            verdict = "kept" if f.get("kept") else "rejected"
            lines.append(f"    held-out {g['metric']}: {g['before']:.4g} -> {g['after']:.4g} ({verdict})")
    for u in report["unexplained"]:
        lines.append(f"! unexplained: {u['statistic']}: {u['evidence']}")
    lines.append(f"time {report['timing']['total_s']:.1f} s")
    return "\n".join(lines)


def write_html(report: dict, folder) -> Path | None:
    """report.html (+ scores.png when matplotlib is available) in `folder`; returns the page."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    image = ""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        findings = report["findings"]
        fig, ax = plt.subplots(figsize=(7, 0.4 * len(findings) + 1))
        names = [f["cause"] if f["cause"] != "unexplained" else f"unexplained ({f.get('candidate')})" for f in findings]
        colours = ["tab:red" if f["significant"] else "tab:gray" for f in findings]
        ax.barh(names[::-1], [f["score"] for f in findings][::-1], color=colours[::-1])
        ax.set_xlabel("score (|t| or z of the difference measured - simulated)")
        ax.set_xscale("symlog", linthresh=3)
        fig.tight_layout()
        fig.savefig(folder / "scores.png", dpi=100)
        plt.close(fig)
        image = '<img src="scores.png" alt="scores">'
    except ImportError:
        pass
    rows = "".join(
        f"<tr><td>{html.escape(str(f['cause']))}</td><td>{'yes' if f['significant'] else 'no'}</td>"
        f"<td>{f['score']:.2f}</td><td>{html.escape(f['evidence'])}</td>"
        f"<td>{html.escape(json.dumps(_plain(f.get('gain'))))}</td></tr>" for f in report["findings"])
    page = folder / "report.html"
    atomic_write_bytes(page, (f"<html><head><meta charset='utf-8'><title>g2r-diagnose</title></head><body>"
                    f"<h1>g2r-diagnose</h1><pre>{html.escape(summary(report))}</pre>{image}"
                    f"<table border=1><tr><th>cause</th><th>significant</th><th>score</th><th>evidence</th>"
                    f"<th>held-out gain</th></tr>{rows}</table></body></html>\n").encode())
    return page
