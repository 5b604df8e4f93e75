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

TITLES = {"noise_model": "Noise", "noise_correlation": "Correlated noise", "black_level": "Black level",
          "white_level": "Clipping level", "lens_shading": "Lens shading", "green_imbalance": "Green imbalance",
          "banding": "Banding (row or column offsets)", "defective_pixels": "Defective pixels",
          "exposure_distribution": "Exposure of the scenes", "illuminant_distribution": "White balance (illuminants)",
          "colour_matrix": "Colour matrices"}


def title(f: dict) -> str:
    """'Noise (noise_model)': plain words, then the cause's name as REPORT.json has it."""
    name = f.get("source") or f.get("candidate") if f["cause"] == "unexplained" else f["cause"]
    words = TITLES.get(name, name or "unexplained")
    return f"{words} ({name})" if name else words


def status(f: dict) -> str:
    """What became of a significant finding: in the extended profile, or not explained."""
    if f.get("kept"):
        return "fixed by the extended profile"
    if f["cause"] == "unexplained":
        return "not explained"
    return "not fixed"


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


def _signed_worst(d) -> float:
    """The component of `d` largest in magnitude, with its sign (0 when none is finite)."""
    d = np.asarray(d, np.float64)
    d = d[np.isfinite(d)]
    return float(d[np.argmax(np.abs(d))]) if d.size else 0.0


def sentence(f: dict) -> str:
    """What differs between the measured files and the profile's simulation, and by how much."""
    cause, d = f.get("source", f["cause"]), np.asarray(f.get("difference") or [], np.float64)
    finite = np.abs(d[np.isfinite(d)])
    worst = float(finite.max()) if finite.size else 0.0
    if cause == "black_level":
        dn = np.asarray(f.get("difference_dn", d), np.float64)
        dn = dn[np.isfinite(dn)]
        if dn.size and np.ptp(dn) <= max(0.1, 0.05 * np.max(np.abs(dn))):   # one offset for every position
            where = f"{abs(float(np.mean(dn))):.2f} DN {'above' if np.mean(dn) > 0 else 'below'}"
        else:
            where = f"{_list(dn, '{:+.2f}')} DN (per CFA position) away from"
        if f.get("scene_evidence"):
            return (f"The sensor's black sits {where} where the profile puts it, inferred from the scenes: their noise "
                    "curve is the profile's shifted by that offset, and their brightness agrees (no dark frames or "
                    "optical-black pixels to measure it on; add some to confirm it).")
        return f"The sensor's black sits {where} where the profile puts it, measured on pixels that see no light."
    if cause == "noise_model":
        w = f.get("worst")
        where = "a burst of frames of one scene" if f.get("temporal") else "flat regions of the files"
        if w:
            text = (f"The camera's noise differs from the profile's: its variance is x{w['ratio']:.2f} the profile's "
                    f"at {100 * w['level']:.2g} % of the range (the surest difference; measured on {where})")
            levels = [(x, r) for x, r in f.get("ratio_by_level") or [] if np.isfinite(r) and r > 0]
            if len(levels) >= 2:
                low, high = min(levels, key=lambda v: v[1]), max(levels, key=lambda v: v[1])
                ratio = lambda r: f"x{r:.2f}" if r >= 0.1 else f"x{r:.2g}"
                text += (f"; over the signal levels measured it ranges from {ratio(low[1])} (at {100 * low[0]:.2g} %) "
                         f"to {ratio(high[1])} (at {100 * high[0]:.2g} %)")
            return text + "."
        return "The camera's noise differs from the profile's noise model (dark and bright signal levels compared)."
    if cause == "white_level":
        direction = "below" if _signed_worst(d) < 0 else "above"
        return (f"The measured files clip (saturate) {100 * worst:.2g} % of the range {direction} the level the "
                "profile clips at.")
    if cause == "lens_shading":
        signed = _signed_worst(d)
        return (f"Relative to the centre, the corners are {100 * abs(math.exp(signed) - 1):.2g} % "
                f"{'darker' if signed < 0 else 'brighter'} than the profile's lens shading makes them "
                "(the colour channel that differs most).")
    if cause == "green_imbalance":
        return f"The two green sites of the colour filter differ by {100 * (math.exp(worst) - 1):.2g} % more than the profile says."
    if cause == "banding":
        return "Rows or columns of the measured files carry offsets (banding) the profile does not simulate."
    if cause == "exposure_distribution":
        signed = _signed_worst(d)
        return (f"The measured scenes are {abs(signed):.2g} stops {'darker' if signed < 0 else 'brighter'} on average "
                "than the profile's exposure model makes them.")
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
    if f["cause"] == "unexplained" and f.get("decide_with"):
        return (f"Not fitted: a black pedestal explains this difference as well as {f['candidate']} does, and a "
                f"wrong cause is worse than none; {f['decide_with']}.")
    if f["cause"] == "unexplained" and f.get("candidate"):
        return (f"The {f['candidate']} extension did not help on files it was not fitted on, so the profile is "
                "left as it is; the difference is real but its cause is not one the audit can fit.")
    return "The audit has no extension for this; the difference is reported so that you can judge it."
