"""Real data: measured files carrying the S20 FE night illuminants (45 gray-card measurements,
street and sodium lamps) against the published method's single-Gaussian profile (fitted with the
sodium lamps, r/g > 1, dropped as "outliers", as the Graphics2RAW code does): the audit must name
the illuminant distribution and a mixture extension must help on held-out files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from g2r_jax.illuminants import distributions as _illuminants
from g2r_jax.profile import schema as _profile
from g2r_jax.audit import diagnose, scenes, simulate, synthetic

DATA = Path(__file__).parents[1] / ".." / "shared" / "data"
NIGHT = DATA / "illuminants" / "s20fe_night_graycard_45.csv"


@pytest.mark.data
@pytest.mark.skipif(not NIGHT.exists(), reason="../shared/data not present")
def test_night_illuminants_need_a_mixture():
    table = np.loadtxt(NIGHT, delimiter=",", skiprows=1)
    chromaticities = table[:, [0, 2]] / table[:, [1]]
    base = synthetic.demo_profile()
    published = chromaticities[chromaticities[:, 0] <= 1.0]
    profile = _profile.replace(base, illuminants=_illuminants.fit_gaussian(published))
    # one measured file per real illuminant: its as-shot neutral is the measured one
    measured = simulate.simulate(profile, scenes.scene_set(len(chromaticities), 77, 120, 180), 3)
    for (mosaic, info), point in zip(measured, chromaticities):
        info.as_shot_neutral = np.array([point[0], 1.0, point[1]])
    report = diagnose(profile, measured, seed=0)
    finding = next(f for f in report["findings"] if f["cause"] == "illuminant_distribution")
    assert finding["significant"] and report["findings"][0] is finding
    assert finding["gain"]["heldout"] and finding["gain"]["after"] < finding["gain"]["before"]
    assert len(finding["params"]["weights"]) >= 2
