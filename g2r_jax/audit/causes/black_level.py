"""`black_level`: the sensor's black sits above (or below) the BlackLevel tag (a black pedestal).

Evidence: only what does not depend on the scene (`black_evidence`): optical-black pixels
(MaskedAreas, margins outside ActiveArea) and dark frames in the measured set. A set without
either has no black-level evidence, and this cause is then not tested (the darkest content of
a scene is not a pedestal: dim scenes have no black).

Test (closed form, no simulation): per CFA position, the files' evidence pooled by inverse
variance (`black_evidence.pooled_offset`) minus the profile's pedestal, z = difference / se with
a resolution floor of `floor` DN; p Bonferroni over the positions. Significant when p is below
the threshold and the difference exceeds `tolerance` of the range.
Extension: `SensorEffects.black_pedestal` (DN per position, one value per colour); held out:
the pedestal fitted on some files (or on one half of the evidence's rows) against the others.
"""

from __future__ import annotations

import numpy as np
from scipy import stats as _scipy_stats

from g2r_jax.audit import black_evidence
from g2r_jax.audit.causes.base import Cause, as_profile_dtype, effects_replaced, per_colour, span

RESOLUTION_DN = 0.05   # added in quadrature to the standard error: below this a DN offset is not resolved


def _evidence(files) -> list:
    return [f.get("black") for f in files if f.get("black") is not None]


class BlackLevel(Cause):
    name = "black_level"
    statistic = ("black level measured where the sensor sees no light (optical-black pixels, dark frames) "
                 "minus the BlackLevel tag and the profile's pedestal, DN per CFA position")
    metric = "rms difference between the held-out black evidence and the profile's black (DN)"
    floor, tolerance = RESOLUTION_DN, 1e-3
    region_heldout = True
    unit = "black level above the BlackLevel tag (DN)"

    def vectors(self, files, profile):
        return np.stack([np.asarray((f.get("black") or {}).get("offset", np.full(4, np.nan)), np.float64)
                         for f in files])

    def test(self, measured, simulated, profile, *, n_permutations=2000, seed=0):
        evidence = _evidence(measured)
        if not evidence:
            return {"cause": self.name, "score": 0.0, "p": 1.0, "magnitude": 0.0, "statistic": self.statistic,
                    "evidence": "no black-level evidence: no optical-black pixels and no dark frames among the "
                                "measured files (the darkest scene content is not used)",
                    "difference": [0.0] * 4, "closed_form": True, "tested": False}
        mean, se, n = black_evidence.pooled_offset(evidence)
        pedestal = np.asarray(profile.effects.black_pedestal, np.float64)
        difference = mean - pedestal
        se = np.sqrt(se**2 + self.floor**2)
        usable = np.isfinite(difference)
        z = np.where(usable, difference / se, 0.0)
        score = float(np.max(np.abs(z)))
        p = float(min(1.0, usable.sum() * 2 * _scipy_stats.norm.sf(score)))
        fraction = np.where(usable, difference / span(profile), 0.0)
        sources = sorted({e["source"] for e in evidence})
        evidence_text = (f"black level from {len(evidence)} file(s) ({', '.join(sources)}): "
                         f"{np.array2string(np.where(usable, mean, np.nan), precision=2)} DN above the tag, the profile "
                         f"says {np.array2string(pedestal, precision=2)} DN; difference "
                         f"{np.array2string(np.where(usable, difference, np.nan), precision=2)} DN "
                         f"(+-{np.array2string(np.where(usable, se, np.nan), precision=2)}), z = {score:.1f}")
        return {"cause": self.name, "score": score, "p": p, "magnitude": float(np.max(np.abs(fraction))),
                "statistic": self.statistic, "evidence": evidence_text, "difference": np.nan_to_num(difference).tolist(),
                "difference_dn": np.nan_to_num(difference).tolist(), "closed_form": True, "tested": True}

    def fit(self, measured, simulated, profile, *, seed=0, key="offset"):
        # one pedestal per colour: two noisy per-green estimates would leave a Gr/Gb offset
        # difference in the extended profile that reads as green imbalance in the next round
        mean, _, _ = black_evidence.pooled_offset(_evidence(measured), key)
        current = np.asarray(profile.effects.black_pedestal, np.float64)
        pedestal = per_colour(profile, np.where(np.isfinite(mean), mean, current))
        return {"black_pedestal_dn": pedestal.tolist(), "offset_fraction": float(np.mean(pedestal / span(profile)))}

    def apply(self, profile, params):
        return effects_replaced(profile, black_pedestal=as_profile_dtype(profile, params["black_pedestal_dn"]))

    def _rms(self, files, profile, key):
        mean, _, _ = black_evidence.pooled_offset(_evidence(files), key)
        pedestal = np.asarray(profile.effects.black_pedestal, np.float64)
        d = (mean - pedestal)[np.isfinite(mean)]
        return float(np.sqrt(np.mean(d**2))) if d.size else 0.0

    def discrepancy(self, measured, simulated, profile, *, seed=0):
        return self._rms(measured, profile, "offset")

    def heldout(self, fit_files, held_files, simulated, profile, simulate_stats, *, seed=0):
        """Files: fit on `fit_files`' evidence, compare on `held_files`'; one file: fit on the
        even tile rows of its evidence, compare on the odd ones."""
        one = len(fit_files) == 1 and fit_files[0] is held_files[0]
        fit_key, held_key = ("A", "B") if one else ("offset", "offset")
        extended = self.apply(profile, self.fit(fit_files, simulated, profile, key=fit_key))
        return self._rms(held_files, profile, held_key), self._rms(held_files, extended, held_key)

    def plot(self, measured, simulated, profile, extended=None):
        files = [f for f in measured if f.get("black") is not None]
        if not files:   # a pedestal inferred from the scenes (`scene_pedestal`): no black to plot
            return None
        values = self.vectors(files, profile)
        pedestal = np.asarray(profile.effects.black_pedestal, np.float64)
        return {"kind": "strip", "measured": values.tolist(), "simulated": [pedestal.tolist()],
                "unit": self.unit, "labels": self.component_labels(4, profile), "simulated_label": "the profile's black",
                "title": "black_level: measured black (optical black, dark frames) against the profile's"}


CAUSE = BlackLevel()
