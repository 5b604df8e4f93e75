"""`defective_pixels`: pixels stuck high or low in many files (hot / dead pixels).

Measures pixels that are outliers against their same-colour neighbours (`stats.outliers`) in
many files, against a binomial chance level (`significance.consistent_outliers`); extension:
`SensorEffects.defect_rows/cols/values`.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from g2r_jax.audit import significance
from g2r_jax.audit.causes.base import Cause, as_profile_dtype, effects_replaced


MIN_FILES = 3


def _group(files):
    """The largest group of files of one size that carry outlier lists (pixel positions only
    compare within one size), or []."""
    files = [f for f in files if f.get("outliers") is not None]
    if not files:
        return []
    shapes = [f["shape"] for f in files]
    common = max(set(shapes), key=shapes.count)
    return [f for f in files if f["shape"] == common]


def _consistent(files):
    return significance.consistent_outliers([f["outliers"] for f in files], files[0]["shape"])


def _control(simulated, profile, shape):
    """(count, positions) the profile itself predicts: from simulated files of the same size, else
    in closed form, its own defect list inside `shape`."""
    same = [f for f in _group(simulated) if f["shape"] == shape]
    if len(same) >= MIN_FILES:
        found = _consistent(same)
        return found["count"], set(zip(found["rows"].tolist(), found["cols"].tolist()))
    e = profile.effects
    own = {(int(r), int(c)) for r, c in zip(np.asarray(e.defect_rows), np.asarray(e.defect_cols))
           if 0 <= r < shape[0] and 0 <= c < shape[1]}
    return len(own), own


class DefectivePixels(Cause):
    name = "defective_pixels"
    statistic = "number of pixels that are outliers against their same-colour neighbours in many files"
    metric = "Jaccard distance between defect sets found in measured and simulated files"
    needs_outliers = True

    def test(self, measured, simulated, profile, *, n_permutations=2000, seed=0):
        group = _group(measured)
        if len(group) < MIN_FILES:
            return {"cause": self.name, "score": 0.0, "p": 1.0, "magnitude": 0.0, "statistic": self.statistic,
                    "evidence": f"needs at least {MIN_FILES} files of one size: not tested", "difference": []}
        found = _consistent(group)
        control_count, _ = _control(simulated, profile, group[0]["shape"])
        excess = found["count"] - control_count
        return {"cause": self.name, "score": found["score"] if excess > 0 else 0.0,
                "p": found["p"] if excess > 0 else 1.0, "magnitude": float(max(excess, 0)),
                "statistic": self.statistic,
                "evidence": f"{found['count']} pixels are outliers in many measured files (chance level "
                            f"{found['expected']:.3g}), {control_count} expected from the profile", "difference": []}

    def plot(self, measured, simulated, profile, extended=None):
        return None

    def fit(self, measured, simulated, profile, *, seed=0):
        found = _consistent(_group(measured))
        effects = profile.effects
        existing = {(int(r), int(c)) for r, c in zip(np.asarray(effects.defect_rows), np.asarray(effects.defect_cols))}
        new = [[int(r), int(c), float(np.clip(v, 0, 1))] for r, c, v in zip(found["rows"], found["cols"], found["values"])
               if (int(r), int(c)) not in existing]
        return {"count": len(new), "defects": new}

    def apply(self, profile, params):
        defects = np.asarray(params["defects"], np.float64).reshape(-1, 3)
        e = profile.effects
        return effects_replaced(
            profile, defect_rows=jnp.concatenate([e.defect_rows, jnp.asarray(defects[:, 0], jnp.int32)]),
            defect_cols=jnp.concatenate([e.defect_cols, jnp.asarray(defects[:, 1], jnp.int32)]),
            defect_values=jnp.concatenate([e.defect_values, as_profile_dtype(profile, defects[:, 2])]))

    def discrepancy(self, measured, simulated, profile, *, seed=0):
        group = _group(measured)
        if not group:
            return 0.0
        a = _consistent(group)
        sa = set(zip(a["rows"].tolist(), a["cols"].tolist()))
        _, sb = _control(simulated, profile, group[0]["shape"])
        return 0.0 if not (sa | sb) else 1.0 - len(sa & sb) / len(sa | sb)


CAUSE = DefectivePixels()
