"""The black-pedestal hypothesis weighed against the noise and exposure findings, for measured
sets without black-level evidence (no dark frames, no optical-black pixels).

A constant offset d above the BlackLevel tag leaves two traces in scene files (issue 29):

- the variance-versus-level curve is the profile's, shifted along the signal axis by d: it meets
  the read-noise floor at d above the tag, not at the tag, so measured from the tag every bin
  reads less variance than the profile predicts, most in the dark bins;
- every file's signal is raised by the same d whatever its exposure, so dim files look brighter
  by more stops than bright ones.

A noise-model error explains the first trace and an exposure error the second; the pedestal
explains both with one number. Here d is fitted to the noise curve alone (the profile's own
noise model, measured from tag + d), its held-out noise discrepancy is compared with the noise
extension's, and the brightness that d predicts (each file's centre percentiles moved by d,
`stats.centre_quantiles`) is checked against the simulated files: evidence the fit never saw.
A constant moves every percentile by exactly that constant, and the neighbour-pair noise levels
by it, so measured files are not measured again for each d; the large-file and burst level
functions have their axis above the tag and take d from the profile (`noise_model.above_black`).

A denoiser that works above a signal level (a phone's, a lossy raw codec's; issue 34) also
lowers the measured variance, and a pedestal fitted to its noise curve can explain part of
that. The two predict different things, and the pedestal must pass both before it is named:

- the darkest values: a pedestal d lifts every pixel, so no scene's darkest content (the dark
  floor, 0.5th percentile of 4 x 4 block means, `stats.dark_floor`) can lie below d by more
  than the noise of a block mean at black (`darkest_values`);
- the low end of the noise curve: a pedestal moves the curve's origin, so the variance deficit
  is largest in the darkest bins, while a knee leaves the low end on the profile's curve and
  lowers the variance above it. Over the bins below the median measured level of large files
  and bursts (closed form), the pedestal's chi-square against the profile's (`low_end`) must
  not be worse by more than LOW_END_CHI2; on such files it must be better by that much to name
  a pedestal, unless the brightness confirms it.

Verdicts (`weigh`): "black_level" when the pedestal explains the noise better than the noise
extension, or as well while the brightness confirms it, and neither the darkest values nor the
low end contradict it; "ruled_out" when they do (the finding stands, the words say why);
"ambiguous" when the two cannot be told apart (dark frames or optical-black pixels would
decide); None otherwise (the finding stands).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from scipy import optimize

from g2r_jax.audit.causes.base import effects_replaced, as_profile_dtype, span as _span
from g2r_jax.measure import folds_of

GRID = np.arange(-0.03, 0.1001, 0.0025)   # pedestals tried, fraction of the range (then refined)
COMPARABLE = 1.25    # the pedestal's held-out noise discrepancy within this factor of the noise extension's: a tie
BRIGHTNESS_T = 3.0   # |t| of the brightness the pedestal predicts beyond which it contradicts the files
CONFIRMED_T = 2.0    # |t| of the brightness difference above which a pedestal that halves it confirms itself
DARKEST_SD = 4.0     # a dark floor this many block-noise sd below the pedestal contradicts it
DARKEST_FIT = 0.1    # ... plus this share of the pedestal (the fit's error: +4 % seen on issue 29's sets)
LOW_END_CHI2 = 25.0  # chi-square change over the low-end bins that decides (5 sd of one bin)
DECIDES = "dark frames (a capture with the lens capped) or optical-black pixels in the measured set would decide"


def with_pedestal(profile, pedestal_dn: float):
    """`profile` with one black pedestal of `pedestal_dn` DN at every CFA position."""
    return effects_replaced(profile, black_pedestal=as_profile_dtype(profile, np.full(4, float(pedestal_dn))))


def measured_from(f: dict, pedestal_dn: float) -> dict:
    """A measured file's statistics as if measured from tag + `pedestal_dn` instead of the black
    they were measured from (`f["pedestal_dn"]`, the runner records it): the neighbour-pair noise
    levels and the centre percentiles move down by the difference, and the brightness with them."""
    span = np.resize(np.asarray(f["span"], np.float64), 4)
    delta = (float(pedestal_dn) - np.resize(np.asarray(f.get("pedestal_dn", 0.0), np.float64), 4)) / span
    out = dict(f)
    if f.get("nlf_level") is not None:
        out["nlf_level"] = np.asarray(f["nlf_level"]) - delta[:, None]
    if f.get("centre_quantiles") is not None:
        q = np.asarray(f["centre_quantiles"], np.float64)
        log = lambda v: np.log2(np.maximum(v, 1e-4)).mean()
        out["brightness"] = np.asarray(f["brightness"], np.float64) + (log(q - delta.mean()) - log(q))
    return out


def noise_discrepancy(files, simulated, profile, pedestal_dn: float, half: str = "B") -> float:
    """noise_model's discrepancy of `files` measured from tag + `pedestal_dn` against the profile
    with that pedestal (`half` of the regions of large files and bursts)."""
    from g2r_jax.audit.causes.noise_model import CAUSE as NOISE

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return NOISE.discrepancy([measured_from(f, pedestal_dn) for f in files], simulated,
                                 with_pedestal(profile, pedestal_dn), half=half)


def fit_pedestal(files, simulated, profile, half: str = "A") -> float:
    """The pedestal (DN) under which the profile's noise model best matches the files' noise
    curve: a grid over GRID of the range, refined by a bounded scalar search around the best."""
    span = float(np.mean(_span(profile)))
    cost = lambda d: noise_discrepancy(files, simulated, profile, d, half)
    values = [cost(g * span) for g in GRID]
    best = int(np.nanargmin(values))
    step = (GRID[1] - GRID[0]) * span
    refined = optimize.minimize_scalar(cost, bounds=(GRID[best] * span - step, GRID[best] * span + step),
                                       method="bounded", options={"xatol": 1e-4 * span})
    return float(refined.x) if refined.fun <= values[best] else float(GRID[best] * span)


def brightness_t(files, simulated, pedestal_dn: float, floor: float = 0.01) -> float:
    """Welch t of the files' mean brightness (measured from tag + `pedestal_dn`) against the
    simulated files'; 0 with fewer than 2 files on either side."""
    m = np.array([measured_from(f, pedestal_dn)["brightness"][0] for f in files], np.float64)
    s = np.array([f["brightness"][0] for f in simulated], np.float64)
    m, s = m[np.isfinite(m)], s[np.isfinite(s)]
    if len(m) < 2 or len(s) < 2:
        return 0.0
    se = np.sqrt(m.var(ddof=1) / len(m) + s.var(ddof=1) / len(s) + floor**2)
    return float((m.mean() - s.mean()) / se)


def darkest_values(files, profile, pedestal_dn: float) -> dict:
    """Whether the scenes' darkest content allows a pedestal of `pedestal_dn` DN above the tag.

    A constant offset raises every pixel, so every file's dark floor (`stats.dark_floor`, per
    position, measured from the tag) is at least the pedestal less the noise of a 4 x 4 block
    mean at black, sqrt(read + 1/12 DN^2) / 4 (the profile's read term at the file's ISO).
    Returns {"contradicted", "floor" (the lowest file's median floor over positions, fraction of
    the range), "allowed" (the lowest floor the pedestal allows), "file" (its name)}."""
    from g2r_jax.audit.causes.noise_model import noise_prediction

    lowest = None
    for f in files:
        floor = np.asarray(f.get("dark_floor", np.full(4, np.nan)), np.float64)
        if not np.all(np.isfinite(floor)):
            continue
        span = np.resize(np.asarray(f["span"], np.float64), 4)
        read = noise_prediction(profile, f["iso"], np.zeros((4, 1)))[2]
        block_sd = np.sqrt(np.maximum(read, 0) + np.asarray(f["quantisation"], np.float64)) / 4
        d = float(pedestal_dn) / span
        allowed = float(np.median(d - DARKEST_SD * block_sd - DARKEST_FIT * np.abs(d)))
        value = float(np.median(floor))
        if lowest is None or value - allowed < lowest["floor"] - lowest["allowed"]:
            lowest = {"floor": value, "allowed": allowed, "file": f.get("name") or ""}
    if lowest is None:
        return {"contradicted": False, "floor": float("nan"), "allowed": float("nan"), "file": ""}
    return dict(lowest, contradicted=lowest["floor"] < lowest["allowed"])


def low_end(files, profile, pedestal_dn: float) -> dict | None:
    """How the pedestal fits the low end of the noise curve against the profile's own black.

    On the closed-form bins (large files' flat blocks, bias-free; bursts' temporal variance),
    the bins below the median measured level of each CFA position: chi-square of
    log(measured / model variance) / se measured from tag + `pedestal_dn` against the profile
    with that pedestal, minus the same at the profile's pedestal. A pedestal moves the curve's
    origin, so on a set with one it lowers the chi-square there; a denoising knee leaves the low
    end on the profile's curve, where a pedestal raises it. Returns {"delta", "bins", "before",
    "after"} or None when the files have no such bins (small files)."""
    from g2r_jax.audit.causes import noise_model as nm

    current = float(np.mean(np.asarray(profile.effects.black_pedestal, np.float64)))

    def z(files_at, profile_at):
        bursts = nm._bursts(files_at)
        if bursts:
            L, se, signal = nm.pooled([nm.temporal_log_ratio(profile_at, f, "all") for f in bursts])
        elif nm._large(files_at):
            L, se, signal = nm.corrected(profile_at, nm._large(files_at), None)[:3]
        else:
            return None, None
        return L / se, signal

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        z0, signal = z([measured_from(f, current) for f in files], profile)
        if z0 is None:
            return None
        z1, _ = z([measured_from(f, pedestal_dn) for f in files], with_pedestal(profile, pedestal_dn))
        both = np.isfinite(z0) & np.isfinite(z1)
        median = np.nanmedian(np.where(both, signal, np.nan), axis=1, keepdims=True)
        low = both & (signal <= median)
    if low.sum() < 2:
        return None
    before, after = float(np.sum(z0[low] ** 2)), float(np.sum(z1[low] ** 2))
    return {"delta": after - before, "bins": int(low.sum()), "before": before, "after": after}


def heldout_noise(files, simulated, profile, *, folds: int, seed: int):
    """(before, after, heldout): the noise discrepancy of held-out files (the folds of
    `gain.cross_validate`) at the profile's pedestal and at the pedestal fitted on the other
    files; one file: fitted on half A of its regions, checked on half B."""
    current = float(np.mean(np.asarray(profile.effects.black_pedestal, np.float64)))
    if len(files) < 2:
        d = fit_pedestal(files, simulated, profile, "A")
        return (noise_discrepancy(files, simulated, profile, current), noise_discrepancy(files, simulated, profile, d),
                "regions" if files[0].get("nlf") is not None or files[0].get("temporal") is not None else False)
    before, after = [], []
    for held in folds_of(len(files), min(folds, len(files)), seed):
        chosen = set(held.tolist())
        fit_files = [f for i, f in enumerate(files) if i not in chosen]
        held_files = [files[i] for i in held]
        d = fit_pedestal(fit_files, simulated, profile, "A")
        before.append(noise_discrepancy(held_files, simulated, profile, current))
        after.append(noise_discrepancy(held_files, simulated, profile, d))
    return float(np.mean(before)), float(np.mean(after)), True


def weigh(top: dict, files, simulated, profile, *, folds: int = 3, seed: int = 0) -> dict | None:
    """Weigh a black pedestal against `top`, a significant noise_model or exposure_distribution
    finding whose extension was cross-validated (`top["gain"]`), on scene files without
    black-level evidence. Returns None (the finding stands) or {"verdict": "black_level",
    "ambiguous" or "ruled_out" (the darkest values or the low end of the noise curve contradict
    the pedestal: the finding stands), "pedestal_dn", "gain" (held-out noise discrepancy before /
    after the pedestal), "brightness_t" (before, after), "darkest", "low_end", "evidence" (words)}."""
    span = float(np.mean(_span(profile)))
    current = float(np.mean(np.asarray(profile.effects.black_pedestal, np.float64)))
    pedestal = fit_pedestal(files, simulated, profile, "A")
    before, after, heldout = heldout_noise(files, simulated, profile, folds=folds, seed=seed)
    t0, t1 = brightness_t(files, simulated, current), brightness_t(files, simulated, pedestal)
    confirmed = abs(t0) >= CONFIRMED_T and abs(t1) <= abs(t0) / 2
    if top["cause"] == "noise_model":
        verdict = _noise_verdict(top, before, after, t0, t1, confirmed)
    else:
        verdict, pedestal, t1 = _exposure_verdict(files, simulated, profile, pedestal, before, after, t1, confirmed)
    if verdict is None:
        return None
    darkest = darkest_values(files, profile, pedestal) if pedestal > current + 1e-3 * span else None
    shape = low_end(files, profile, pedestal)
    words = (f"a black pedestal of {pedestal:.1f} DN ({100 * pedestal / span:.2f} % of the range) above the tag, "
             f"fitted to the noise curve with the profile's noise model: held-out noise discrepancy "
             f"{before:.3g} -> {after:.3g} (the {top['cause']} extension: {top['gain']['before']:.3g} -> "
             f"{top['gain']['after']:.3g}); the brightness it predicts: t = {t0:.1f} -> {t1:.1f} against the "
             f"simulated files")
    against = _contradictions(darkest, shape, span)
    if against:
        verdict, words = "ruled_out", f"{words}; ruled out: {against}"
    elif verdict == "black_level" and shape is not None and shape["delta"] > -LOW_END_CHI2 and not confirmed:
        # large files and bursts show the low end: a pedestal must lower the deficit there
        verdict = "ambiguous"
        words += (f"; the low end of the noise curve does not confirm it (chi-square {shape['before']:.1f} -> "
                  f"{shape['after']:.1f} over {shape['bins']} bins)")
    return {"verdict": verdict, "pedestal_dn": pedestal, "offset_fraction": pedestal / span,
            "gain": {"metric": "rms of the noise discrepancy on held-out files, measured from the fitted black",
                     "before": before, "after": after, "heldout": heldout, "folds": folds},
            "brightness_t": [t0, t1], "darkest": darkest, "low_end": shape, "evidence": words}


def _noise_verdict(top, before, after, t0, t1, confirmed):
    """"black_level", "ambiguous" or None for a pedestal weighed against a noise_model finding."""
    extension = top["gain"]["after"]
    contradicted = abs(t1) > BRIGHTNESS_T and abs(t1) > abs(t0) + 1.0
    if contradicted or not after < before:
        return None
    if after < extension or (after <= COMPARABLE * extension + 0.02 and confirmed):
        return "black_level"
    return "ambiguous" if after <= COMPARABLE * extension + 0.02 else None


def _exposure_verdict(files, simulated, profile, pedestal, before, after, t1, confirmed):
    """(verdict, pedestal, t) for a pedestal weighed against an exposure_distribution finding (the
    noise curve did not differ): the pedestal must explain the brightness."""
    span = float(np.mean(_span(profile)))
    current = float(np.mean(np.asarray(profile.effects.black_pedestal, np.float64)))
    if confirmed and after < before and abs(pedestal - current) > 1e-3 * span:
        return "black_level", pedestal, t1
    # the pedestal the brightness alone asks for: can the noise curve rule it out?
    asked = GRID[int(np.argmin([abs(brightness_t(files, simulated, g * span)) for g in GRID]))] * span
    at_asked = noise_discrepancy(files, simulated, profile, asked, "all")
    at_current = noise_discrepancy(files, simulated, profile, current, "all")
    if abs(asked - current) < 1e-3 * span or at_asked > COMPARABLE * at_current + 0.02:
        return None, pedestal, t1
    return "ambiguous", float(asked), brightness_t(files, simulated, asked)


def _contradictions(darkest, shape, span) -> str:
    """Words for the evidence against a pedestal (empty when none)."""
    out = []
    if darkest is not None and darkest["contradicted"]:
        out.append(f"the darkest content of {Path(darkest['file']).name or 'a file'} lies "
                   f"{100 * darkest['floor']:.2f} % of the range above the tag, below the "
                   f"{100 * darkest['allowed']:.2f} % a pedestal allows")
    if shape is not None and shape["delta"] > LOW_END_CHI2:
        out.append(f"the low end of the noise curve follows the profile's curve (chi-square over the "
                   f"{shape['bins']} lowest bins {shape['before']:.1f}, with the pedestal {shape['after']:.1f}): "
                   f"the variance is lower above a level, as a denoiser's, not from the origin")
    return "; ".join(out)
