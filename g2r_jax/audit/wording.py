"""Plain words for the audit report: one sentence per finding in the user's units, what to do
about it, p-values as bounds, and what the order of the findings means. The technical evidence
(test statistics, per-position vectors) stays in the report's details."""

from __future__ import annotations

import math
import re

import numpy as np

RANKING = ("Findings are ordered by how sure the audit is: significant ones first, then by score (|z| or |t|) "
           "up to {cap:g}; beyond that every difference is certain, and they are ordered by how many times "
           "they exceed the smallest difference worth reporting for their cause (within a factor of two, "
           "noise comes before levels, levels before optics).")

_COLOURS = {0: "red", 1: "green", 2: "blue"}


def p_words(p) -> str:
    """'p = 0.0042', or a bound 'p < 1e-12' below 0.001 (never 'p 0': a p-value of 0 is below
    the smallest double, 'p < 1e-300')."""
    if p is None or not np.isfinite(p):
        return "p unknown"
    if p >= 1e-3:
        return f"p = {p:.2g}"
    exponent = max(-300, math.ceil(math.log10(p)) if p > 0 else -300)
    return f"p < 1e{exponent}" if exponent < -3 else "p < 0.001"


def clean(text: str) -> str:
    """Evidence text without 'nan' (a component with no data reads 'n/a')."""
    return re.sub(r"\bnan\b", "n/a", str(text))


def _list(values, fmt="{:+.2g}") -> str:
    values = [v for v in np.asarray(values, np.float64).ravel() if np.isfinite(v)]
    return ", ".join(fmt.format(v) for v in values) if values else "n/a"


def sentence(f: dict) -> str:
    """What differs between the measured files and the profile's simulation, and by how much."""
    cause, d = f.get("source", f["cause"]), np.asarray(f.get("difference") or [], np.float64)
    finite = np.abs(d[np.isfinite(d)])
    worst = float(finite.max()) if finite.size else 0.0
    if cause == "black_level":
        return (f"The sensor's black sits {_list(f.get('difference_dn', d), '{:+.2f}')} DN (per CFA position) "
                "away from where the profile puts it, measured on pixels that see no light.")
    if cause == "noise_model":
        w = f.get("worst")
        where = "a burst of frames of one scene" if f.get("temporal") else "flat regions of the files"
        if w:
            return (f"The camera's noise differs from the profile's: its variance is x{w['ratio']:.2f} the profile's "
                    f"at {100 * w['level']:.2g} % of the range (measured on {where}).")
        return "The camera's noise differs from the profile's noise model (dark and bright signal levels compared)."
    if cause == "white_level":
        return f"The measured files clip at a level {100 * worst:.2g} % of the range away from the profile's."
    if cause == "lens_shading":
        return (f"The corners are {100 * (math.exp(worst) - 1):.2g} % brighter or darker relative to the centre "
                "than the profile's lens shading makes them.")
    if cause == "green_imbalance":
        return f"The two green sites of the colour filter differ by {100 * (math.exp(worst) - 1):.2g} % more than the profile says."
    if cause == "banding":
        return "Rows or columns of the measured files carry offsets (banding) the profile does not simulate."
    if cause == "exposure_distribution":
        return f"The measured files are {worst:.2g} stops brighter or darker than the profile's exposure model gives."
    if cause == "illuminant_distribution":
        return "The measured files' white balance (as-shot neutrals) lies outside what the profile's illuminant model draws."
    if cause == "defective_pixels":
        return "Some pixels are stuck or hot in many measured files and the profile does not list them."
    if cause == "noise_correlation":
        return ("The measured noise is correlated between neighbouring pixels (denoising, compression or "
                "demosaicing in the camera); the profile simulates white noise.")
    if cause == "colour_matrix":
        return "The measured colour charts' colours differ from what the profile's colour matrices predict."
    return f"The measured files differ from the simulation in: {f.get('statistic', cause)}."


def action(f: dict, report: dict) -> str:
    """What the user can do about the finding."""
    written = report.get("extended_profile")
    if f.get("kept"):
        where = (f"the extended profile {written} includes it: convert with `g2r-convert --profile {written}`"
                 if written else "rerun with --extended-profile PATH to save a profile that includes it")
        checked = (f.get("gain") or {}).get("heldout")
        how = ("it lowers the discrepancy on data it was not fitted on" if checked else
               "it lowers the discrepancy on the one file it was fitted on; audit more files to check it")
        return f"Fixed by the fitted extension ({how}); {where}."
    if f["cause"] == "unexplained" and f.get("candidate"):
        return (f"The {f['candidate']} extension did not help on files it was not fitted on, so the profile is "
                "left as it is; the difference is real but its cause is not one the audit can fit.")
    return "The audit has no extension for this; the difference is reported so that you can judge it."
