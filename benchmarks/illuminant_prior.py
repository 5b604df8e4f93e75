"""Leave-one-camera-out validation of the camera-independent illuminant prior.

For each camera of the measured sets (`g2r_jax.illuminants.prior_fit.measured_sets`: Gehler-Shi
Canon EOS-1D and EOS 5D, S20 FE night), the prior is fitted to the *other* cameras, mapped into
the held-out camera through its DNG colour model, and its samples are compared with that
camera's real illuminants in the camera's (r/g, b/g):
- energy distance (Szekely & Rizzo 2013; `distributions.energy_distance`), lower is better;
- coverage: share of the real lights within 0.05 of a sample; `far`: share beyond 0.10.
Rows to beat: the supplement's A-D65 CCT locus (S3; `distributions.fit_locus`, from the camera's
matrices alone) and a Gaussian + hull fitted to a random half of the held-out camera's own lights,
scored on the other half (an oracle: it has seen the camera's scenes). Every model draws
`SAMPLES` neutrals per seed; figures are means over `SEEDS` seeds (and half-splits).

    python benchmarks/illuminant_prior.py [--data ../shared/data] [--few-lights | --rpi]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from g2r_jax.illuminants import distributions as D  # noqa: E402
from g2r_jax.illuminants.prior import model_for_camera  # noqa: E402
from g2r_jax.illuminants.prior_fit import fit_prior, measured_sets  # noqa: E402

SAMPLES = 2000
SEEDS = 3
RADIUS = 0.05


def chromaticities(neutrals) -> np.ndarray:
    """(r/g, b/g) of camera neutrals (N, 3)."""
    neutrals = np.asarray(neutrals, np.float64)
    return neutrals[:, [0, 2]] / neutrals[:, 1:2]


def score(real, samples) -> np.ndarray:
    """(energy distance, coverage within RADIUS, share farther than 2 RADIUS) of real vs samples."""
    nearest = np.linalg.norm(real[:, None] - samples[None], axis=-1).min(axis=1)
    return np.array([D.energy_distance(samples, real), np.mean(nearest <= RADIUS), np.mean(nearest > 2 * RADIUS)])


def model_score(model, real) -> np.ndarray:
    """`score` averaged over SEEDS draws of SAMPLES neutrals from `model`."""
    return np.mean([score(real, chromaticities(D.sample_neutrals(jax.random.PRNGKey(seed), model, SAMPLES)))
                    for seed in range(SEEDS)], axis=0)


def gaussian_half_score(real) -> np.ndarray:
    """Gaussian + hull fitted to a random half, scored on the other half (mean over SEEDS splits)."""
    rows = []
    for seed in range(SEEDS):
        order = np.random.default_rng(seed).permutation(len(real))
        half = len(real) // 2
        model = D.fit_gaussian(real[order[:half]], dtype=np.float64)
        samples = chromaticities(D.sample_neutrals(jax.random.PRNGKey(seed), model, SAMPLES))
        rows.append(score(real[order[half:]], samples))
    return np.mean(rows, axis=0)


def leave_one_camera_out(sets, presets=("day", "day_night")) -> list[dict]:
    """One row per (held-out camera, model): camera, model, lights, energy, coverage, far."""
    rows = []
    for held in sets:
        others = [s for s in sets if s is not held]
        prior = fit_prior(others)
        real = chromaticities(held.neutrals)
        models = [("S3 locus (A-D65)", lambda: model_score(D.fit_locus(held.colour_model, dtype=np.float64), real)),
                  ("Gaussian+hull, own half", lambda: gaussian_half_score(real))]
        models += [(f"prior '{p}' (other cameras)",
                    lambda p=p: model_score(model_for_camera(held.colour_model, p, prior, dtype=np.float64), real))
                   for p in presets if p in prior.presets]
        for label, run in models:
            energy, coverage, far = run()
            rows.append(dict(camera=held.name, model=label, lights=len(real), trained_on=[s.name for s in others],
                             energy=float(energy), coverage=float(coverage), far=float(far)))
    return rows


def few_lights_rows(sets, counts=(3, 5, 10, 20, 40), repeats=10) -> list[dict]:
    """Gaussian + hull fitted to `count` random lights of a camera, scored on the rest (mean over
    `repeats` draws): how many lights a profile needs before its own Gaussian beats the prior."""
    rows = []
    for measured in sets:
        real = chromaticities(measured.neutrals)
        for count in counts:
            scores = []
            for seed in range(repeats):
                order = np.random.default_rng(seed).permutation(len(real))
                model = D.fit_gaussian(real[order[:count]], dtype=np.float64)
                samples = chromaticities(D.sample_neutrals(jax.random.PRNGKey(seed), model, SAMPLES))
                scores.append(score(real[order[count:]], samples))
            energy, coverage, far = np.mean(scores, axis=0)
            rows.append(dict(camera=measured.name, lights=count, energy=float(energy), coverage=float(coverage),
                             far=float(far)))
    return rows


RPI_PROFILES = {"rpi_hq_imx477": "imx477", "rpi_camera_module_3_imx708": "imx708", "rpi_global_shutter_imx296": "imx296"}


def rpi_rows(data_root) -> list[dict]:
    """The prior (all measured sets) and the S3 locus, each mapped into a shipped Raspberry Pi profile
    (its three-illuminant DNG model), against that sensor's measured AWB locus `rpi.awb.ct_curve`:
    the camera neutrals of Raspberry Pi's calibration lights. Few lights, none a scene: coverage only."""
    import json
    import re

    from g2r_jax.illuminants.prior import load_prior
    from g2r_jax.profile.schema import load_profile

    rows = []
    for name, sensor in RPI_PROFILES.items():
        colour = load_profile(name, dtype=np.float64).colour
        text = (data_root / "cameras/rpi_libcamera/vc4" / f"{sensor}.json").read_text()
        tuning = json.loads(re.sub(r",(\s*[}\]])", r"\1", text))   # libcamera tolerates trailing commas
        awb = next(a["rpi.awb"] for a in tuning["algorithms"] if "rpi.awb" in a)
        curve = np.asarray(awb["ct_curve"], np.float64).reshape(-1, 3)
        for label, model in (("S3 locus", D.fit_locus(colour, dtype=np.float64)),
                             ("prior 'day'", model_for_camera(colour, "day", load_prior(), dtype=np.float64))):
            _, coverage, far = model_score(model, curve[:, 1:])
            rows.append(dict(camera=name, model=label, lights=len(curve), span=(curve[0, 0], curve[-1, 0]),
                             coverage=float(coverage), far=float(far)))
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--few-lights", action="store_true",
                        help="instead: a Gaussian + hull fitted to 3-40 of a camera's own lights, scored on the rest")
    parser.add_argument("--rpi", action="store_true",
                        help="instead: coverage of the Raspberry Pi sensors' measured AWB loci (shipped rpi_* profiles)")
    args = parser.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    if args.rpi:
        print(f"| profile | model | calibration lights (CT) | within {RADIUS} | beyond {2 * RADIUS} |")
        print("|---|---|---|---|---|")
        for row in rpi_rows(args.data):
            low, high = row["span"]
            print(f"| {row['camera']} | {row['model']} | {row['lights']} ({low:.0f}-{high:.0f} K) | "
                  f"{row['coverage']:.2f} | {row['far']:.2f} |")
        return 0
    if args.few_lights:
        print(f"| camera | own lights fitted | energy distance | within {RADIUS} | beyond {2 * RADIUS} |")
        print("|---|---|---|---|---|")
        for row in few_lights_rows(measured_sets(args.data)):
            print(f"| {row['camera']} | {row['lights']} | {row['energy']:.3f} | {row['coverage']:.2f} | {row['far']:.2f} |")
        return 0
    rows = leave_one_camera_out(measured_sets(args.data))
    print(f"| held-out camera (lights) | model | energy distance | within {RADIUS} | beyond {2 * RADIUS} |")
    print("|---|---|---|---|---|")
    for row in rows:
        print(f"| {row['camera']} ({row['lights']}) | {row['model']} | {row['energy']:.3f} | "
              f"{row['coverage']:.2f} | {row['far']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
