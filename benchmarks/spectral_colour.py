"""The spectral sensor model (issue 11) against the DNG-matrix model, in one run.

    python benchmarks/spectral_colour.py                       # all sections (needs ../shared/data)
    python benchmarks/spectral_colour.py --sections table cost --quick
    python benchmarks/spectral_colour.py --json results.json

Sections:
- table:      issue 11's experiment. Ground truth: the Canon EOS 600D's measured sensitivities
              (rawtoaces). ColorChecker (Ohta) under 7 locus lights (2500 K - D75) and 6 off-locus
              lights (FL2, FL11, LED-B3, HP1 sodium, HP1+LED-B3, FL11+D65); chromatic mean angular
              error (18 patches, degrees) of: the DNG matrices (the 600D's Adobe A/D65 pair, exactly
              `unprocess(colour="matrix")`), Mallett-Yuksel upsampling (`colour="spectral"`) and
              Jakob-Hanika upsampling (colour-science's optimiser per patch, and the shipped 9^3 lattice
              that `colour="spectral-jakob2019"` interpolates), each with the true light and with the
              light `unprocess` infers from the neutral (locus + all lamp families).
- estimate:   sensitivities estimated from DNG matrices only. Leave-one-out over the 77 published
              sets (basis without the camera, matrices for A and D65 synthesised from its curves on
              the 190 rawtoaces training reflectances): spectral angle to the measured curves. And
              the table's experiment with the estimate from the real Adobe matrices (600D,
              1Ds Mark III, D40) standing in for the measured curves in the spectral model.
- gehler:     the real Gehler-Shi charts (568 images; Canon EOS-1D and 5D, no measured curves: the
              sensitivities are estimated from their D65 ColorMatrix only): predicted vs recorded
              raw RGB of the chromatic patches under each image's measured illuminant.
- cost:       `unprocess` per 12-MP frame (3024 x 4032) under jit, matrix vs spectral vs
              spectral-jakob2019 (noise off and on); best of a few interleaved runs.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
DATA = ROOT / ".." / "shared" / "data"
CANON_600D_JSON = "spectral/rawtoaces/camera/Canon_EOS_600D_380_780_5.json"


def print_summary(title, table):
    from g2r_jax.colour.spectral import accuracy

    print(f"\n{title}\n{'model':30s} {'locus (7)':>10s} {'off (6)':>8s} {'HP1 mean (max)':>16s}")
    for model, row in accuracy.summarise(table).items():
        print(f"{model:30s} {row['locus']:10.2f} {row['off']:8.2f} {row['HP1'][0]:9.2f} ({row['HP1'][1]:.1f})")
    lights = list(next(iter(table.values())))
    print("per light (chromatic mean, degrees):\n" + f"{'':30s}" + "".join(f"{l[:10]:>11s}" for l in lights))
    for model, rows in table.items():
        print(f"{model:30s}" + "".join(f"{rows[l][0]:11.2f}" for l in lights))


def section_table():
    import g2r_jax
    from g2r_jax.io.sensitivities import read_sensitivities
    from g2r_jax.colour.spectral import accuracy

    truth = read_sensitivities(DATA / CANON_600D_JSON).values
    profile = g2r_jax.load_profile("Canon600D", dtype=np.float64)
    table = accuracy.colour_table(truth, colour_model, jakob_hanika="both")
    print_summary("Canon EOS 600D, measured sensitivities as ground truth", table)
    return {"canon600d": accuracy.summarise(table), "per_light": table}


def section_estimate():
    import g2r_jax
    from g2r_jax.io.sensitivities import read_sensitivities
    from g2r_jax.colour.spectral import accuracy, build_tables
    from g2r_jax.colour.spectral.estimate import build_basis, calibration_light, estimate_from_matrices

    results = build_tables.leave_one_out(DATA)
    angles = np.array([r["angle"] for r in results])
    mean_curve = np.stack([v for _, _, v in build_tables.published_sensitivities(DATA)]).mean(0)
    baseline = np.array([build_tables.spectral_angle(mean_curve, r["truth"]) for r in results])
    print(f"\nLeave-one-out, {len(results)} measured sets: spectral angle estimate vs measured (degrees, R G B)")
    print(f"  estimate from synthesised A/D65 matrices: mean {np.round(angles.mean(0), 2)}, "
          f"median {np.round(np.median(angles, 0), 2)}, 90th pct {np.round(np.percentile(angles, 90, 0), 2)}")
    print(f"  (mean curve of all sets, no fit:          mean {np.round(baseline.mean(0), 2)})")
    out = {"loo_mean_angle": angles.mean(0).tolist(), "loo_median_angle": np.median(angles, 0).tolist(),
           "mean_curve_angle": baseline.mean(0).tolist(), "real_matrices": {}}
    cases = [("Canon600D", CANON_600D_JSON, None),
             ("Canon1DsMkIII", "spectral/rawtoaces/camera/Canon_EOS-1Ds_Mark_III_380_780_5.json", None),
             ("NikonD40", "spectral/camspec/camspec_database.txt", "Nikon D40")]
    sets = build_tables.published_sensitivities(DATA)
    for name, path, camera in cases:
        measured = read_sensitivities(DATA / path, camera)
        truth = measured.values
        colour_model = _colour_model(name)
        held_out = build_tables.camera_key(measured.camera)          # both sources' copies of this camera
        basis = build_basis(np.stack([v for k, _, v in sets if k != held_out]))
        lights = [calibration_light(code) for code in colour_model.calibration_illuminants]
        estimate = estimate_from_matrices(lights, np.asarray(colour_model.color_matrix), basis)
        angle = build_tables.spectral_angle(estimate, truth)
        table = accuracy.colour_table(truth, colour_model, jakob_hanika=None, simulated_sensitivities=estimate)
        summary = accuracy.summarise(table)
        print_summary(f"{name}: spectral model with sensitivities estimated from its Adobe matrices "
                      f"(angle to measured R G B: {np.round(angle, 1)}; this camera held out of the basis)", table)
        out["real_matrices"][name] = {"angle": angle.tolist(), "summary": summary}
    return out


def _colour_model(name: str):
    """The camera's DNG colour model: its shipped profile's, or, for a NUS camera that is not shipped
    (no noise measurement), its Adobe matrix pair from ../shared/data/cameras/color_matrices.json."""
    import g2r_jax
    from g2r_jax.colour.dng_model import DngColourModel

    if name in g2r_jax.shipped_profiles():
        return g2r_jax.load_profile(name, dtype=np.float64).colour
    tags = json.loads((DATA / "cameras" / "color_matrices.json").read_text())[name]
    return DngColourModel.from_tags([17, 21], [tags["ColorMatrix_StandardLightA_tag17"], tags["ColorMatrix_D65_tag21"]],
                                    dtype=np.float64)


def _gehler_shi(charts_dir=None) -> dict:
    """{camera name: ChartSet} of the Gehler-Shi charts: from the chart CSVs written by
    benchmarks/gehler_shi_charts.py (`--charts-dir`, read by `g2r_jax.charts.read_charts`), or from
    the release's .mat files by that script's own loader (black 129 removed from the 5D images)."""
    from gehler_shi_charts import CAMERAS, charts_for, load_release

    from g2r_jax.colour.charts import read_charts

    if charts_dir is not None:
        return {name: read_charts(Path(charts_dir) / f"gehler_shi_{key}.csv") for key, (name, _, _) in CAMERAS.items()}
    release = load_release(DATA / "illuminants" / "gehler_shi")
    return {name: charts_for(release, key) for key, (name, _, _) in CAMERAS.items()}


def section_gehler(charts_dir=None):
    import jax

    from g2r_jax.colour import conversions as _colour
    from g2r_jax.colour import dng_model as _dng
    from g2r_jax.colour.dng_model import DngColourModel
    from g2r_jax.colour.charts import chart_linear_srgb
    from g2r_jax.colour.spectral import accuracy
    from g2r_jax.colour.spectral.estimate import estimate_sensitivities
    from g2r_jax.measure import angular_error_degrees
    from g2r_jax.colour.spectral.illuminant_spectra import choose_lamp_families

    sys.path.insert(0, str(ROOT / "benchmarks"))
    charts = _gehler_shi(charts_dir)
    cameras = json.loads((DATA / "cameras" / "gehler_shi_cameras.json").read_text())
    srgb = chart_linear_srgb()
    reflectances = {"spectral": accuracy.mallett_yuksel_reflectances(srgb),
                    "jakob2019": accuracy.jakob_hanika_lattice_reflectances(srgb)}
    out = {}
    for camera, chart_set in charts.items():
        entry = cameras[camera]
        matrix = np.asarray(entry["color_matrix_d65"], np.float64).reshape(3, 3) / entry["scale"]
        white = entry["white_level"] - entry.get("black_level", 0) - 50     # below the clipping level
        colour_model = DngColourModel.from_tags([21], [matrix], dtype=np.float64)
        estimate, _ = estimate_sensitivities(colour_model)
        neutrals = chart_set.illuminant / chart_set.illuminant[:, 1:2]
        patches_all = chart_set.patches
        images = range(len(neutrals))
        xy, _ = _dng.camera_neutrals_to_xy(np.asarray(neutrals, np.float32),
                                           DngColourModel.from_tags([21], [matrix]), throw=False)
        cct = np.asarray(jax.jit(_colour.xy_to_CCT)(xy))
        families = choose_lamp_families(neutrals[:, [0, 2]], cct, estimate)
        errors = {"matrix": [], "spectral": [], "jakob2019": []}
        for index, neutral in zip(images, neutrals):
            recorded = patches_all[index]
            valid = np.all(np.isfinite(recorded), 1) & np.all(recorded < white, 1) & np.all(recorded > 0, 1)
            valid[18:] = False
            if valid.sum() < 6:
                continue
            predictions = {"matrix": accuracy.predict_matrix(srgb, neutral, colour_model)}
            light = accuracy.inferred_light(neutral, estimate, colour_model, families)
            for method, r in reflectances.items():
                predictions[method] = accuracy.predict_spectral(r, light, estimate)
            for method, predicted in predictions.items():
                errors[method].append(angular_error_degrees(predicted[valid], recorded[valid]).mean())
        out[camera] = {m: {"images": len(e), "mean": float(np.mean(e)), "median": float(np.median(e)),
                           "better_than_matrix": float(np.mean(np.array(e) < np.array(errors["matrix"])))}
                       for m, e in errors.items()}
        print(f"\nGehler-Shi {camera} ({len(errors['matrix'])} images; sensitivities estimated from its D65 "
              f"ColorMatrix; lamp families {families or 'none'}): per-image chromatic mean angular error (degrees)")
        for method, row in out[camera].items():
            print(f"  {method:10s} mean {row['mean']:.2f}  median {row['median']:.2f}  "
                  f"images better than matrix {100 * row['better_than_matrix']:.0f} %")
    return out


def section_cost(quick: bool, repeats: int):
    import jax

    import g2r_jax
    from g2r_jax.profile.editing import attach_spectral

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from throughput import test_image

    height, width = (756, 1008) if quick else (3024, 4032)
    image = test_image(height, width)
    profile = attach_spectral(g2r_jax.load_profile("s20fe_night"))
    key = jax.random.PRNGKey(0)
    results = {}
    for noise in (False, True):
        runs = {colour: jax.jit(lambda k, im, c=colour: g2r_jax.unprocess(k, im, profile, colour=c, noise=noise)[0])
                for colour in ("matrix", "spectral", "spectral-jakob2019")}
        for run in runs.values():
            run(key, image).block_until_ready()
        times = {c: [] for c in runs}
        for _ in range(repeats):                       # interleaved, so load changes hit all alike
            for colour, run in runs.items():
                start = time.perf_counter()
                run(key, image).block_until_ready()
                times[colour].append(time.perf_counter() - start)
        best = {c: min(t) for c, t in times.items()}
        results[f"noise_{'on' if noise else 'off'}"] = best
        print(f"\nunprocess per {height}x{width} frame, noise {'on' if noise else 'off'} (best of {repeats}, "
              f"{jax.devices()[0].platform}; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores):")
        for colour, seconds in best.items():
            print(f"  {colour:20s} {1000 * seconds:8.1f} ms   x{seconds / best['matrix']:.2f} of matrix")
    return results


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sections", nargs="*", default=["table", "estimate", "gehler", "cost"])
    parser.add_argument("--quick", action="store_true", help="756 x 1008 frames for the cost section")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--charts-dir", type=Path,
                        help="read the Gehler-Shi chart CSVs written by benchmarks/gehler_shi_charts.py instead of the .mat files")
    args = parser.parse_args(argv)
    if not DATA.exists() and set(args.sections) - {"cost"}:
        print(f"{DATA} is absent: only the cost section can run", file=sys.stderr)
        return 2
    results = {}
    for section in args.sections:
        start = time.perf_counter()
        if section == "cost":
            results[section] = section_cost(args.quick, args.repeats)
        elif section == "gehler":
            results[section] = section_gehler(args.charts_dir)
        else:
            results[section] = globals()[f"section_{section}"]()
        print(f"[{section}: {time.perf_counter() - start:.0f} s]")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=lambda a: np.asarray(a).tolist()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
