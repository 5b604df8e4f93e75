"""`defective_pixels`: pixels stuck high or low in many files (hot / dead pixels).

Measures pixels that are outliers against their same-colour neighbours (`stats.outliers`) in
many files, against a binomial chance level (`significance.consistent_outliers`); extension:
`SensorEffects.defect_rows/cols/values`.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .. import significance
from .base import Cause, as_profile_dtype, effects_replaced


def _consistent(files):
    return significance.consistent_outliers([f["outliers"] for f in files], files[0]["shape"])


class DefectivePixels(Cause):
    name = "defective_pixels"
    statistic = "number of pixels that are outliers against their same-colour neighbours in many files"
    metric = "Jaccard distance between defect sets found in measured and simulated files"
    needs_outliers = True

    def test(self, measured, simulated, profile, *, n_permutations=2000, seed=0):
        found, control = _consistent(measured), _consistent(simulated)
        excess = found["count"] - control["count"]
        return {"cause": self.name, "score": found["score"] if excess > 0 else 0.0,
                "p": found["p"] if excess > 0 else 1.0, "magnitude": float(max(excess, 0)),
                "statistic": self.statistic,
                "evidence": f"{found['count']} pixels are outliers in many measured files (chance level "
                            f"{found['expected']:.3g}), {control['count']} in simulated files", "difference": []}

    def fit(self, measured, simulated, profile, *, seed=0):
        found = _consistent(measured)
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
        a, b = _consistent(measured), _consistent(simulated)
        sa, sb = set(zip(a["rows"].tolist(), a["cols"].tolist())), set(zip(b["rows"].tolist(), b["cols"].tolist()))
        return 0.0 if not (sa | sb) else 1.0 - len(sa & sb) / len(sa | sb)


CAUSE = DefectivePixels()
