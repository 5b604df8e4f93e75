"""The registry of audit causes: one module per cause, one line per cause here.

Each module defines `CAUSE`, an instance of a `base.Cause` subclass that holds everything about
that cause: what it measures (`statistic`, `vectors`), how it is tested (`test`, `floor`,
`tolerance`), how its extension is fitted and applied (`fit`, `apply`) and validated
(`metric`, `discrepancy`, `heldout`). `diagnose` loops over `REGISTRY` and owns only the order:
test every cause, take the strongest significant one, cross-validate its extension, keep it and
re-test the rest against the extended profile (explain away), report.

To add a cause: write `causes/<name>.py` with a `Cause` subclass (override `vectors` or set
`key` to a `stats.file_statistics` key; override `test` if the default maxT permutation test
over files does not fit; implement `fit` and `apply`, or set `extensible = False`), then add
its `CAUSE` to `REGISTRY` below. Its name enters the vocabulary (`vocabulary.CAUSES`) when it is
extensible. The order of `REGISTRY` is the vocabulary order; ties in score keep it.

Interface (see `base.Cause` for defaults):

    name, statistic, metric: str; floor, tolerance: float; extensible, needs_outliers: bool
    vectors(files, profile) -> (n_files, k)
    test(measured, simulated, profile, *, n_permutations, seed) -> finding dict
        (cause, score, p, magnitude, statistic, evidence, difference)
    is_significant(finding, threshold) -> bool
    fit(measured, simulated, profile, *, seed) -> JSON-ready params
    apply(profile, params) -> extended SensorProfile
    discrepancy(measured, simulated, profile, *, seed) -> float (lower is better)
    heldout(fit_files, held_files, simulated, profile, simulate_stats, *, seed) -> (before, after)
"""

from __future__ import annotations

from g2r_jax.audit.causes import (
    banding,
    black_level,
    colour_matrix,
    defective_pixels,
    exposure_distribution,
    green_imbalance,
    illuminant_distribution,
    lens_shading,
    noise_correlation,
    noise_model,
    white_level)
from g2r_jax.audit.causes.base import Cause

REGISTRY: tuple[Cause, ...] = (
    illuminant_distribution.CAUSE,
    exposure_distribution.CAUSE,
    noise_model.CAUSE,
    black_level.CAUSE,
    white_level.CAUSE,
    green_imbalance.CAUSE,
    lens_shading.CAUSE,
    defective_pixels.CAUSE,
    banding.CAUSE,
    noise_correlation.CAUSE,
    colour_matrix.CAUSE,          # evidence: measured charts (diagnose(..., charts=...))
)
BY_NAME = {cause.name: cause for cause in REGISTRY}


def get(name: str) -> Cause:
    """The registered cause called `name` (KeyError naming the known ones otherwise)."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"no audit cause {name!r}; registered: {', '.join(BY_NAME)}") from None


__all__ = ["REGISTRY", "BY_NAME", "Cause", "get"]
