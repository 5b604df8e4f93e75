"""Held-out gain of an extension: the discrepancy between measured files the extension was not
fitted on and files simulated by the profile before and after the extension (K-fold
cross-validation over measured files; Stone, "Cross-validatory choice and assessment of
statistical predictions", JRSS B 1974). Lower is better; an extension is kept only if the mean
held-out discrepancy goes down. What "discrepancy" means is the cause's own
(`Cause.discrepancy`, `Cause.heldout`, `Cause.metric`).
"""

from __future__ import annotations

import numpy as np

from g2r_jax.measure import folds_of


def cross_validate(cause, measured: list, simulated: list, profile, simulate_stats, *,
                   folds: int = 3, seed: int = 0) -> dict:
    """K-fold held-out gain of `cause`'s extension (`cause`: a registered `Cause`).

    **Arguments:** `measured`, `simulated`: per-file statistics (the latter from `profile`);
    `simulate_stats(profile, cause_name)`: per-file statistics of files simulated by another
    profile (same scenes and random draws as `simulated`, so before/after differ only by the extension).

    **Returns:** {"metric", "before", "after", "heldout", "folds"}; heldout is True for held-out
    files, "regions" for one file checked on regions the fit did not use, False otherwise.
    """
    if len(measured) < 2:
        # one file: the fit and the check use the same file; a cause with region-level evidence
        # fits on one half of its regions and checks on the other (`Cause.region_heldout`)
        b, a = cause.heldout(measured, measured, simulated, profile, simulate_stats, seed=seed)
        return {"metric": cause.metric, "before": float(b), "after": float(a),
                "heldout": "regions" if getattr(cause, "region_heldout", False) else False, "folds": 1}
    before, after = [], []
    for held in folds_of(len(measured), folds, seed):
        held_set = set(held.tolist())
        fit_files = [f for i, f in enumerate(measured) if i not in held_set]
        held_files = [measured[i] for i in held]
        b, a = cause.heldout(fit_files, held_files, simulated, profile, simulate_stats, seed=seed)
        before.append(b)
        after.append(a)
    return {"metric": cause.metric, "before": float(np.mean(before)), "after": float(np.mean(after)),
            "heldout": True, "folds": folds}
