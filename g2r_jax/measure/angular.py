"""Illuminant-estimation error, written once for the package: the recovery angular error and the
summary statistics papers report.

- Angular error (Hordley & Finlayson, "Reevaluation of color constancy algorithm performance",
  JOSA A 23(5), 2006, Eq. 1): the angle between the estimated and the true illuminant as
  vectors in camera RGB, independent of their scale. We evaluate it as
  atan2(|e x t|, e . t), equal to arccos(e . t / (|e| |t|)) but accurate for small angles,
  where the arccos form loses half its digits.
- Summary (Graphics2RAW supplement Table S4, after Hordley & Finlayson 2006 and Gijsenij et al.
  2011): mean, median, and the means of the best and worst quarter of the sorted errors, a
  quarter being round(N / 4) images (at least one), as the paper's released evaluation counts it.
"""

from __future__ import annotations

import numpy as np


def _rows(name: str, values, invalid: str) -> tuple[np.ndarray, np.ndarray]:
    """(rows (M, 3) float64, bad (M,)): `values` (..., 3) flattened to rows; a bad row is not
    finite or all zero, an error unless `invalid` is "nan"."""
    array = np.asarray(values, dtype=np.float64)
    if array.ndim == 0 or array.shape[-1] != 3:
        raise ValueError(f"{name}: expected RGB rows of shape (N, 3) or (3,), got shape {np.shape(values)}")
    array = array.reshape(-1, 3)
    not_finite = ~np.isfinite(array).all(axis=1)
    zero = ~(np.abs(array) > 0).any(axis=1)
    if invalid == "raise" and not_finite.any():
        raise ValueError(f"{name}: row {int(np.argmax(not_finite))} is not finite ({array[np.argmax(not_finite)]})")
    if invalid == "raise" and zero.any():
        raise ValueError(f"{name}: row {int(np.argmax(zero))} is zero; an illuminant needs a direction")
    return np.where((not_finite | zero)[:, None], 1.0, array), not_finite | zero


def angular_error_degrees(estimate, truth, *, invalid: str = "raise") -> np.ndarray:
    """Angle in degrees between each estimated and true illuminant (Hordley & Finlayson 2006).

    **Arguments:** `estimate`, `truth`: RGB rows (..., 3) of one shape, of any positive scale
    (each row is normalised here; a single (3,) vector is one row); `invalid`: "raise" (default)
    or "nan", what a non-finite or all-zero row gives (chart patches a file lacks are NaN).
    **Returns:** float64 errors in [0, 180], shape (...) ((1,) for one (3,) vector).
    **Raises:** ValueError for mismatched shapes, and for non-finite or all-zero rows unless
    `invalid` is "nan".
    """
    if invalid not in ("raise", "nan"):
        raise ValueError(f"invalid must be 'raise' or 'nan', not {invalid!r}")
    if np.shape(estimate) != np.shape(truth):
        raise ValueError(f"estimate has shape {np.shape(estimate)} but truth has {np.shape(truth)}")
    est, est_bad = _rows("estimate", estimate, invalid)
    ref, ref_bad = _rows("truth", truth, invalid)
    est = est / np.linalg.norm(est, axis=1, keepdims=True)
    ref = ref / np.linalg.norm(ref, axis=1, keepdims=True)
    sine = np.linalg.norm(np.cross(est, ref), axis=1)
    cosine = np.sum(est * ref, axis=1)
    errors = np.where(est_bad | ref_bad, np.nan, np.degrees(np.arctan2(sine, cosine)))
    return errors.reshape(np.shape(estimate)[:-1] or (1,))


def error_summary(errors) -> dict:
    """Mean, median, best25 and worst25 of a set of angular errors (Table S4's columns).

    best25 / worst25: the mean of the round(N / 4) smallest / largest errors (at least one).
    **Raises:** ValueError for an empty or non-finite set.
    """
    values = np.asarray(errors, dtype=np.float64).ravel()
    if values.size == 0:
        raise ValueError("no errors to summarise")
    if not np.isfinite(values).all():
        raise ValueError(f"errors contain non-finite values (first at index {int(np.argmax(~np.isfinite(values)))})")
    ordered = np.sort(values)
    quarter = max(1, int(np.round(values.size / 4.0)))
    return {"mean": float(ordered.mean()), "median": float(np.median(ordered)),
            "best25": float(ordered[:quarter].mean()), "worst25": float(ordered[-quarter:].mean())}
