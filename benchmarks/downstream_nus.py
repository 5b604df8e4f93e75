"""The paper's illuminant-estimation experiment on real images (Graphics2RAW Table 2 / S1 / S4),
for the nine NUS cameras: estimators trained on synthetic RAW of the CARLA CG frames (UPI,
published recipe, g2r_jax shipped / fitted / one DNG), on the real training folds, and on the
controls, tested on the real images of each camera (`g2r_jax.downstream.illuminant.experiment`).

Data: ../shared/data/estimation/nus/<camera>.npz (real thumbnails, measured illuminants) and
../shared/data/cg/carla/*.png. Profiles: the shipped profile of the camera; Canon1DsMkIII,
FujifilmXM1 and SamsungNX2000 have none: their Adobe ColorMatrix pair from
../shared/data/cameras/color_matrices.json on the Canon600D profile's sensor (levels, noise,
exposure), lights from the cross-camera prior mapped through their matrices (as shipped
profiles without measured lights have them).

    python benchmarks/downstream_nus.py [--cameras Canon600D,NikonD40] [--seeds 3] [--n 500]
        [--estimators cnn,moments,histogram] [--rows ...] [--illuminant-model auto] [--lights 25]
        [--jobs 2] [--json out/downstream_nus.json] [--markdown out/downstream_nus.md]
    python benchmarks/downstream_nus.py --labelled 10,30,100,all --rows real,real_plus_fitted,real_plus_upi,fitted
    python benchmarks/downstream_nus.py --summary out/a.json,out/b.json    # the tables of earlier runs

Prints one table per camera as it finishes, then the summary across cameras. With --json the
results are written after each camera (atomically, per-image errors included), and a run stopped
and started again with the same --json keeps the cameras it holds and runs the others
(`downstream_runner.py`, shared with the ISP benchmark). `--summary` merges its files by camera,
row and estimator: runs of different --rows give one table of every row, a later file winning.
`--labelled` (issue 48, augmentation): each camera once per number of labelled real files that
'real' and the augmented rows ('real_plus_fitted', 'real_plus_upi': the recipe chosen on the
training files, `g2r_jax.downstream.illuminant.augmentation`) train on, drawn from the training
folds; then the curve (mean of the cameras per row and number).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
import downstream_runner as runner  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
NUS = DATA / "estimation" / "nus"
CARLA = DATA / "cg" / "carla"
CAMERAS = ("Canon1DsMkIII", "Canon600D", "FujifilmXM1", "NikonD40", "NikonD5200", "OlympusEPL6", "PanasonicGX1",
           "SamsungNX2000", "SonyA57")
TEMPLATE = "Canon600D"


def camera_profile(name: str):
    """The shipped profile, or the camera's matrix pair on the template's sensor, without a content
    model: the benchmarks apply the content model they measure to the CG views themselves
    (`shipped_content_model` is the one a shipped profile carries)."""
    import g2r_jax
    from g2r_jax.colour.dng_model import DngColourModel
    from g2r_jax.pipeline import without_content
    from g2r_jax.profile.fitting import illuminant_model_for
    from g2r_jax.profile.schema import replace

    if name in g2r_jax.shipped_profiles():
        return without_content(g2r_jax.load_profile(name))
    tags = json.loads((DATA / "cameras" / "color_matrices.json").read_text())[name]
    colour = DngColourModel.from_tags((17, 21), (np.reshape(tags["ColorMatrix_StandardLightA_tag17"], (3, 3)),
                                                 np.reshape(tags["ColorMatrix_D65_tag21"], (3, 3))))
    template = without_content(g2r_jax.load_profile(TEMPLATE))
    return replace(template, colour=colour, illuminants=illuminant_model_for(np.zeros((0, 2)), colour, "prior"))


def shipped_content_model(name: str, colour_model):
    """The content model a shipped profile of NUS camera `name` carries (profiles/build_shipped_profiles.py):
    the prior's 'scenes' table with the camera's own scenes left out of its medians and spread,
    through the camera's colour matrices, and the prior's texture without the camera's scenes."""
    import dataclasses

    from g2r_jax.content import prior_scenes_model
    from g2r_jax.content.prior import prior_texture, real_scenes_without, scene_covariance, texture_covariance

    model = prior_scenes_model(colour_model, real_scenes_without(DATA, name), scene_covariance(DATA, name),
                               "prior without " + name)
    return dataclasses.replace(model, texture=prior_texture(texture_covariance(DATA, name), "prior without " + name))


def other_camera(name: str, cameras) -> str:
    """The camera whose images are the other-content control: the next one in CAMERAS."""
    index = CAMERAS.index(name)
    return CAMERAS[(index + 1) % len(CAMERAS)]


def _arguments(argv):
    """The command line: the runner's shared arguments, then this benchmark's own."""
    from g2r_jax.downstream.illuminant import experiment

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    runner.add_arguments(parser, CAMERAS)
    parser.add_argument("--rows", default=",".join(r for r in experiment.ROWS if r not in experiment.CONTENT_ROWS),
                        help="default: every row but the content model's (benchmarks/content_model.py measures those)")
    parser.add_argument("--estimators", default="cnn,moments,histogram")
    parser.add_argument("--n", type=int, default=500)
    parser.add_argument("--illuminant-model", default="auto")
    parser.add_argument("--lights", type=int, help="fit the lights to this many training files only "
                        "(the number-of-DNGs ablation of Table S6)")
    parser.add_argument("--labelled", default="", help="the augmentation curve: numbers of labelled real files, "
                        "e.g. 10,30,100,all (each camera runs once per number)")
    parser.add_argument("--jobs", type=int, default=1, help="cameras run in this many processes at once")
    return parser.parse_args(argv)


def main(argv=None) -> int:
    """Run the cameras (or print --summary); 0 when done, 2 without the data."""
    args = _arguments(argv)
    if args.summary:
        return _summary(args.summary.split(","))
    if not NUS.is_dir() or not CARLA.is_dir():
        print(f"cannot run: needs {NUS} and {CARLA}", file=sys.stderr)
        return 2
    cameras, rows, estimators = args.cameras.split(","), args.rows.split(","), tuple(args.estimators.split(","))
    counts = [None if v == "all" else int(v) for v in args.labelled.split(",") if v] or [None]
    jobs = {camera_key(name, count, counts): (name, rows, estimators, args.seeds, args.n, args.illuminant_model,
                                             args.lights, cameras, count)
            for name in cameras for count in counts}

    def closing(entries, seconds):
        """The closing tables of the JSON entries so far."""
        return closing_lines(results_from_entries(entries), rows, estimators, bool(args.labelled), seconds)

    benchmark = runner.CameraBenchmark(
        run=run_camera, entry=result_entry, camera_lines=camera_lines,
        kept_lines=lambda key, entry: camera_lines(key, result_from_entry(entry)), closing_lines=closing,
        header=lambda seconds: {"seconds": seconds, "n": args.n}, is_done=is_result_entry)
    runner.run_cameras(benchmark, jobs, json_path=args.json, markdown_path=args.markdown, processes=args.jobs)
    return 0


def camera_key(name: str, count, counts) -> str:
    """The JSON key of one camera's run: the camera, or with --labelled "camera@count" ("@all")."""
    if len(counts) == 1 and counts[0] is None:
        return name
    return f"{name}@{'all' if count is None else count}"


def camera_lines(key: str, result) -> list:
    """The markdown block of one camera: its table and each estimator's sentence."""
    from g2r_jax.downstream.illuminant import reporting

    images = len(next(iter(result.errors.values()))[0])
    block = [f"## {key} ({images} real images; {result.seconds:.0f} s)", "", reporting.table(result), ""]
    return block + [reporting.sentence(result, e) for e in result.estimators] + [""]


def closing_lines(results, rows, estimators, labelled: bool, seconds: float) -> list:
    """The markdown after the cameras: the summary (the rows and estimators asked for, then any
    other the results hold), the labelled-files curve with --labelled, the time."""
    rows = runner.merged_order(rows, *(result.rows for result in results.values()))
    estimators = runner.merged_order(estimators, *(result.estimators for result in results.values()))
    lines = ["## All cameras: mean error (degrees), pooled over seeds", "", summary_table(results, rows, estimators), ""]
    if labelled:
        lines += ["## Labelled real files: mean of the cameras (degrees)", "", curve_table(results, rows, estimators), ""]
    return lines + [f"Total {seconds / 60:.1f} min."]


def _summary(paths) -> int:
    """Print the tables of earlier runs' JSON files, merged by camera, row and estimator (a later
    file's value winning for a cell both hold; a cell no file holds left empty)."""
    entries, _ = runner.read_runs(paths, is_done=is_result_entry)
    results = results_from_entries(entries)
    if not results:
        print("no results in " + ", ".join(paths), file=sys.stderr)
        return 2
    rows = runner.merged_order(*(result.rows for result in results.values()))
    estimators = runner.merged_order(*(result.estimators for result in results.values()))
    print("## All cameras: mean error (degrees), pooled over seeds\n\n" + summary_table(results, rows, estimators))
    if any("@" in key for key in results):
        print("\n## Labelled real files: mean of the cameras (degrees)\n\n" + curve_table(results, rows, estimators))
        for e in estimators:
            print(f"\n## {e}: real alone -> real + g2r_jax, per camera\n\n" + camera_curve_table(results, e))
    return 0


def _labelled_counts(results) -> list:
    """The numbers of labelled files among the keys ("camera@count"), ascending, 'all' last."""
    counts = {key.split("@")[1] for key in results if "@" in key}
    return sorted(counts, key=lambda c: (c == "all", int(c) if c != "all" else 0))


def camera_curve_table(results, estimator: str) -> str:
    """Markdown: per camera and number of labelled files, real alone -> real + g2r_jax (change)."""
    counts = _labelled_counts(results)
    cameras = list(dict.fromkeys(key.split("@")[0] for key in results if "@" in key))
    out = ["| camera | " + " | ".join(f"{c} files" for c in counts) + " |", "|---|" + "---|" * len(counts)]
    for camera in cameras:
        cells = []
        for count in counts:
            r = results.get(f"{camera}@{count}")
            if r is None or not all((row, estimator) in r.errors for row in ("real", "real_plus_fitted")):
                cells.append("")
                continue
            alone, added = (r.summary(row, estimator)["mean"] for row in ("real", "real_plus_fitted"))
            cells.append(f"{alone:.2f} -> {added:.2f} ({added / alone - 1:+.0%})")
        out.append(f"| {camera} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def is_result_entry(entry: dict) -> bool:
    """Whether a JSON entry holds a result (its per-image errors), not a run to make again."""
    return "errors" in entry


def result_entry(result) -> dict:
    """One camera's JSON entry: its summaries, decompositions and per-image errors."""
    from g2r_jax.downstream.illuminant import reporting

    return {**result.to_dict(), "decomposition": {e: reporting.decomposition(result, e) for e in result.estimators},
            "errors": {f"{row}/{e}": [np.asarray(a).tolist() for a in per_seed]
                       for (row, e), per_seed in result.errors.items()}}


def result_from_entry(entry: dict):
    """The `ExperimentResult` of a JSON entry (per-image errors rebuilt)."""
    from g2r_jax.downstream.illuminant.experiment import ExperimentResult

    errors = {tuple(name.split("/")): [np.asarray(a) for a in per_seed] for name, per_seed in entry["errors"].items()}
    recipes = {tuple(name.split("/")): v for name, v in entry.get("recipes", {}).items()}
    return ExperimentResult(camera=entry["camera"], rows=tuple(entry["rows"]), estimators=tuple(entry["estimators"]),
                            seeds=tuple(entry["seeds"]), errors=errors, seconds=entry["seconds"], notes=entry["notes"],
                            recipes=recipes, labelled=entry.get("labelled"), files=entry.get("files", 0))


def results_from_entries(entries: dict) -> dict:
    """{key: ExperimentResult} of the JSON entries that hold results."""
    return {key: result_from_entry(entry) for key, entry in entries.items() if is_result_entry(entry)}


def run_camera(job):
    """One camera's experiment (a worker of --jobs)."""
    from PIL import Image

    from g2r_jax.downstream.base import real_sets
    from g2r_jax.downstream.illuminant import experiment
    from g2r_jax.runtime import compile_cache

    compile_cache.enable(program="g2r_jax-downstream")
    name, rows, estimators, seeds, n, illuminant_model, lights, cameras, labelled = job
    cg = [np.asarray(Image.open(f).convert("RGB")) for f in sorted(CARLA.glob("*.png"))]
    real = real_sets.load_nus(NUS / f"{name}.npz")
    other = None
    if "other_content" in rows:
        partner = other_camera(name, cameras)
        other = (real_sets.load_nus(NUS / f"{partner}.npz"), camera_profile(partner))
    return experiment.illuminant_experiment(
        real, camera_profile(name), cg, rows=rows, estimators=estimators, seeds=tuple(range(seeds)), n=n,
        illuminant_model=illuminant_model, lights=lights, other=other, labelled=labelled,
        progress=lambda m: print(f"  {m}", file=sys.stderr, flush=True))


def _means(result, rows, estimator) -> dict:
    """{row: mean error} of the rows `result` holds for `estimator`."""
    return {row: result.summary(row, estimator)["mean"] for row in rows if (row, estimator) in result.errors}


def curve_table(results, rows, estimators) -> str:
    """Markdown: per estimator and number of labelled files, each row's error averaged over the
    cameras that hold it, and the augmented row against real alone (where the same cameras hold
    both)."""
    out = ["| estimator | labelled files | " + " | ".join(rows) + " | real + g2r_jax vs real |",
           "|---|---|" + "---|" * (len(rows) + 1)]
    for e in estimators:
        for count in _labelled_counts(results):
            parts = [r for key, r in results.items() if key.endswith(f"@{count}")]
            holding = {row: [r for r in parts if (row, e) in r.errors] for row in rows}
            means = {row: float(np.mean([r.summary(row, e)["mean"] for r in held]))
                     for row, held in holding.items() if held}
            if not means:
                continue
            change = (f"{means['real_plus_fitted'] / means['real'] - 1:+.0%}"
                      if {"real", "real_plus_fitted"} <= set(means) and holding["real"] == holding["real_plus_fitted"]
                      else "")
            cells = [f"{means[row]:.2f}" if row in means else "" for row in rows]
            out.append(f"| {e} | {count} | " + " | ".join(cells) + f" | {change} |")
    return "\n".join(out)


def summary_table(results, rows, estimators) -> str:
    """Markdown: per camera and estimator, each row's mean error (empty where the camera lacks the
    row) and g2r_jax fitted against UPI."""
    from g2r_jax.downstream.illuminant.experiment import ROWS

    head = "| camera | estimator | " + " | ".join(ROWS[r] for r in rows) + " | g2r_jax fitted vs UPI |"
    out = [head, "|---|---|" + "---|" * (len(rows) + 1)]
    for name, result in results.items():
        for e in estimators:
            means = _means(result, rows, e)
            if not means:
                continue
            gain = (f"{100 * (1 - means['fitted'] / means['upi']):.0f} % lower" if "fitted" in means and "upi" in means
                    else "")
            cells = [f"{means[r]:.2f}" if r in means else "" for r in rows]
            out.append(f"| {name} | {e} | " + " | ".join(cells) + f" | {gain} |")
    return "\n".join(out)


if __name__ == "__main__":
    sys.exit(main())
