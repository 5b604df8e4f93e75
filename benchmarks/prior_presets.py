"""How often `auto` would leave the day preset of the illuminant prior for day and indoor scenes
(the NUS cameras' measured lights) and keep the night preset for night scenes (the S20 FE's
gray-card lights), by the number of lights and the rule (issue 33; docs validation page
illuminant_models, "Which prior preset").

    python benchmarks/prior_presets.py [--draws 2000]

Per light: the log likelihood of each preset (`prior.camera_prior(colour, preset)`) minus the day
preset's, in the camera's raw chromaticities through its shipped matrices. A random set of n
lights takes a night preset when the sum over the set exceeds `PRESET_EVIDENCE` ("total"), and
with the median rule also when the median light's exceeds `PRESET_MEDIAN_EVIDENCE`.
Data: ../shared/data/estimation/nus/*.npz and ../shared/data/illuminants/s20fe_night_graycard_105.csv.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from downstream_nus import CAMERAS, NUS, camera_profile  # noqa: E402

SIZES = (1, 2, 3, 4, 5, 9)
S20_LIGHTS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "illuminants" / "s20fe_night_graycard_105.csv"


def preset_evidence(lights, colour) -> list:
    """Per-light log likelihood ratios (n,) of each non-day preset the matrices can carry."""
    from g2r_jax.illuminants.distributions import mixture_log_likelihood
    from g2r_jax.illuminants.prior import camera_prior

    day = np.asarray(mixture_log_likelihood(camera_prior(colour, "day").model, lights))
    out = []
    for preset in ("night", "day_night"):
        try:
            out.append(np.asarray(mixture_log_likelihood(camera_prior(colour, preset).model, lights)) - day)
        except ValueError:
            continue
    return out


def share_leaving_day(ratios, n, draws, rng, median_rule: bool) -> float:
    from g2r_jax.illuminants.choice import PRESET_EVIDENCE, PRESET_MEDIAN_EVIDENCE

    hits = 0
    for _ in range(draws):
        pick = rng.choice(len(ratios[0]), n, replace=False)
        hits += any(r[pick].sum() > PRESET_EVIDENCE and (not median_rule or np.median(r[pick]) > PRESET_MEDIAN_EVIDENCE)
                    for r in ratios)
    return hits / draws


def main(argv=None) -> int:
    import g2r_jax
    from g2r_jax.downstream.base import real_sets
    from g2r_jax.illuminants.distributions import neutral_to_chromaticity

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--draws", type=int, default=2000, help="random sets per camera and size")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(0)
    nus = {}
    for name in CAMERAS:
        lights = neutral_to_chromaticity(np.asarray(real_sets.load_nus(NUS / f"{name}.npz").illuminants, np.float64))
        nus[name] = preset_evidence(lights, camera_profile(name).colour)
    s20 = preset_evidence(np.loadtxt(S20_LIGHTS, delimiter=",", skiprows=1)[:, [0, 2]],
                          g2r_jax.load_profile("s20fe_night").colour)
    print("| rule | " + " | ".join(f"n = {n}" for n in SIZES) + " |")
    print("|---|" + "---|" * len(SIZES))
    for median_rule in (False, True):
        rule = "total and median" if median_rule else "total only"
        cells = []
        for n in SIZES:
            shares = [share_leaving_day(r, n, args.draws, rng, median_rule) for r in nus.values()]
            cells.append(f"{100 * np.mean(shares):.2f} % ({100 * max(shares):.2f})")
        print(f"| {rule}: NUS day/indoor sets leaving day, mean of cameras (worst) | " + " | ".join(cells) + " |")
        cells = [f"{100 * share_leaving_day(s20, n, args.draws, rng, median_rule):.1f} %" for n in SIZES]
        print(f"| {rule}: S20 FE night sets given a night preset | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
