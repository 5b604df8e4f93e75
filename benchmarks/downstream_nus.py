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
and started again with the same --json keeps the cameras it holds and runs the others. `--labelled`
(issue 48, augmentation): each camera once per number of labelled real files that 'real' and the
augmented rows ('real_plus_fitted', 'real_plus_upi': the recipe chosen on the training files,
`g2r_jax.downstream.illuminant.augmentation`) train on, drawn from the training folds; then the curve
(mean of the cameras per row and number).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
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
    the prior's 'cast' target with the camera's own scenes left out, through its colour matrices."""
    from g2r_jax.content import prior_cast_model
    from g2r_jax.content.prior import real_scenes_without

    return prior_cast_model(colour_model, real_scenes_without(DATA, name), "prior without " + name)


def other_camera(name: str, cameras) -> str:
    """The camera whose images are the other-content control: the next one in CAMERAS."""
    index = CAMERAS.index(name)
    return CAMERAS[(index + 1) % len(CAMERAS)]


def main(argv=None) -> int:
    from g2r_jax.downstream.illuminant import experiment, reporting

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", default=",".join(CAMERAS))
    parser.add_argument("--rows", default=",".join(r for r in experiment.ROWS if r not in experiment.CONTENT_ROWS),
                        help="default: every row but the content model's (benchmarks/content_model.py measures those)")
    parser.add_argument("--estimators", default="cnn,moments,histogram")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--n", type=int, default=500)
    parser.add_argument("--illuminant-model", default="auto")
    parser.add_argument("--lights", type=int, help="fit the lights to this many training files only "
                        "(the number-of-DNGs ablation of Table S6)")
    parser.add_argument("--labelled", default="", help="the augmentation curve: numbers of labelled real files, "
                        "e.g. 10,30,100,all (each camera runs once per number)")
    parser.add_argument("--jobs", type=int, default=1, help="cameras run in this many processes at once")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--markdown", type=Path)
    parser.add_argument("--summary", help="comma-separated JSON files of earlier runs: print their tables, run nothing")
    args = parser.parse_args(argv)
    if args.summary:
        return _summary(args.summary.split(","))
    if not NUS.is_dir() or not CARLA.is_dir():
        print(f"cannot run: needs {NUS} and {CARLA}", file=sys.stderr)
        return 2
    cameras = args.cameras.split(",")
    rows = args.rows.split(",")
    estimators = tuple(args.estimators.split(","))
    start = time.perf_counter()
    counts = [None if v == "all" else int(v) for v in args.labelled.split(",") if v] or [None]
    keys = [name if len(counts) == 1 and counts[0] is None else f"{name}@{'all' if c is None else c}"
            for name in cameras for c in counts]
    jobs = [(name, rows, estimators, args.seeds, args.n, args.illuminant_model, args.lights, cameras, c)
            for name in cameras for c in counts]
    results = _earlier(args.json)
    todo = [(key, job) for key, job in zip(keys, jobs) if key not in results]
    for key in keys:
        if key in results:
            print(f"  {key}: kept from {args.json}", file=sys.stderr, flush=True)
    if args.jobs > 1:
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(args.jobs) as pool:
            for key, result in zip([k for k, _ in todo], pool.imap(run_camera, [j for _, j in todo])):
                results[key] = result
                _write_json(args, results, estimators, time.perf_counter() - start)
    else:
        for key, job in todo:
            results[key] = run_camera(job)
            _write_json(args, results, estimators, time.perf_counter() - start)
    results = {key: results[key] for key in keys}
    lines = []
    for name, result in results.items():
        block = [f"## {name} ({len(result.errors[(rows[0], estimators[0])][0])} real images; {result.seconds:.0f} s)",
                 "", reporting.table(result), ""]
        block += [reporting.sentence(result, e) for e in estimators] + [""]
        lines += block
    print("\n".join(lines), flush=True)
    summary = summary_table(results, rows, estimators)
    total = time.perf_counter() - start
    lines += ["## All cameras: mean error (degrees), pooled over seeds", "", summary, ""]
    if args.labelled:
        lines += ["## Labelled real files: mean of the cameras (degrees)", "", curve_table(results, rows, estimators), ""]
    lines += [f"Total {total / 60:.1f} min."]
    print("\n".join(lines[-5:]))
    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text("\n".join(lines) + "\n")
    _write_json(args, results, estimators, total)
    return 0


def _summary(paths) -> int:
    """Print the tables of earlier runs' JSON files (a later file's camera wins)."""
    results = {}
    for path in paths:
        results.update(_earlier(Path(path)))
    if not results:
        print("no results in " + ", ".join(paths), file=sys.stderr)
        return 2
    first = next(iter(results.values()))
    rows, estimators = list(first.rows), list(first.estimators)
    print("## All cameras: mean error (degrees), pooled over seeds\n\n" + summary_table(results, rows, estimators))
    if any("@" in key for key in results):
        print("\n## Labelled real files: mean of the cameras (degrees)\n\n" + curve_table(results, rows, estimators))
        for e in estimators:
            print(f"\n## {e}: real alone -> real + g2r_jax, per camera\n\n" + camera_curve_table(results, e))
    return 0


def camera_curve_table(results, estimator: str) -> str:
    """Markdown: per camera and number of labelled files, real alone -> real + g2r_jax (change)."""
    counts = sorted({key.split("@")[1] for key in results if "@" in key}, key=lambda c: (c == "all", int(c) if c != "all" else 0))
    cameras = list(dict.fromkeys(key.split("@")[0] for key in results if "@" in key))
    out = ["| camera | " + " | ".join(f"{c} files" for c in counts) + " |", "|---|" + "---|" * len(counts)]
    for camera in cameras:
        cells = []
        for count in counts:
            r = results.get(f"{camera}@{count}")
            if r is None or not {"real", "real_plus_fitted"} <= set(r.rows):
                cells.append("")
                continue
            alone, added = (r.summary(row, estimator)["mean"] for row in ("real", "real_plus_fitted"))
            cells.append(f"{alone:.2f} -> {added:.2f} ({added / alone - 1:+.0%})")
        out.append(f"| {camera} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def _write_json(args, results, estimators, seconds) -> None:
    """The results so far as JSON (atomically): summaries, decompositions and per-image errors."""
    from g2r_jax.downstream.illuminant import reporting
    from g2r_jax.io.atomic import atomic_write_bytes

    if not args.json:
        return
    args.json.parent.mkdir(parents=True, exist_ok=True)
    document = {name: {**r.to_dict(), "decomposition": {e: reporting.decomposition(r, e) for e in estimators},
                       "errors": {f"{row}/{e}": [np.asarray(a).tolist() for a in per_seed]
                                  for (row, e), per_seed in r.errors.items()}}
                for name, r in results.items()}
    atomic_write_bytes(args.json, json.dumps({"seconds": seconds, "n": args.n, "cameras": document}).encode())


def _earlier(path) -> dict:
    """The results of an earlier run's --json (per-image errors rebuilt into `ExperimentResult`s)."""
    from g2r_jax.downstream.illuminant.experiment import ExperimentResult

    if not path or not Path(path).is_file():
        return {}
    try:
        cameras = json.loads(Path(path).read_text())["cameras"]
    except (OSError, ValueError, KeyError) as error:
        print(f"  {path}: not read ({error}); every camera runs", file=sys.stderr)
        return {}
    out = {}
    for key, doc in cameras.items():
        if "errors" not in doc:
            continue
        errors = {tuple(name.split("/")): [np.asarray(a) for a in per_seed] for name, per_seed in doc["errors"].items()}
        recipes = {tuple(name.split("/")): v for name, v in doc.get("recipes", {}).items()}
        out[key] = ExperimentResult(camera=doc["camera"], rows=tuple(doc["rows"]), estimators=tuple(doc["estimators"]),
                                    seeds=tuple(doc["seeds"]), errors=errors, seconds=doc["seconds"], notes=doc["notes"],
                                    recipes=recipes, labelled=doc.get("labelled"), files=doc.get("files", 0))
    return out


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


def curve_table(results, rows, estimators) -> str:
    """Markdown: per estimator and number of labelled files, each row's error averaged over the
    cameras, and the augmented row against real alone."""
    counts = sorted({key.split("@")[1] for key in results if "@" in key}, key=lambda c: (c == "all", int(c) if c != "all" else 0))
    out = ["| estimator | labelled files | " + " | ".join(rows) + " | real + g2r_jax vs real |",
           "|---|---|" + "---|" * (len(rows) + 1)]
    for e in estimators:
        for count in counts:
            parts = [r for key, r in results.items() if key.endswith(f"@{count}")]
            means = {row: float(np.mean([r.summary(row, e)["mean"] for r in parts])) for row in rows}
            change = (f"{means['real_plus_fitted'] / means['real'] - 1:+.0%}"
                      if {"real", "real_plus_fitted"} <= set(rows) else "")
            out.append(f"| {e} | {count} | " + " | ".join(f"{means[row]:.2f}" for row in rows) + f" | {change} |")
    return "\n".join(out)


def summary_table(results, rows, estimators) -> str:
    from g2r_jax.downstream.illuminant.experiment import ROWS

    head = "| camera | estimator | " + " | ".join(ROWS[r] for r in rows) + " | g2r_jax fitted vs UPI |"
    out = [head, "|---|---|" + "---|" * (len(rows) + 1)]
    for name, result in results.items():
        for e in estimators:
            means = {r: result.summary(r, e)["mean"] for r in rows}
            gain = (f"{100 * (1 - means['fitted'] / means['upi']):.0f} % lower" if "fitted" in means and "upi" in means
                    else "")
            out.append(f"| {name} | {e} | " + " | ".join(f"{means[r]:.2f}" for r in rows) + f" | {gain} |")
    return "\n".join(out)


if __name__ == "__main__":
    sys.exit(main())
