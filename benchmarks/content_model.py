"""The content model (issue 32) on the NUS illuminant-estimation test: estimators trained on
g2r_jax RAW of the CARLA frames with and without the content model fitted to each camera's real
training images (without their labels), UPI on the same content, and real training.

Protocol, per camera and seed (the 3 folds of the downstream benchmark, `g2r_jax.measure.folds_of`):
- the lights are fitted to the training folds' measured illuminants ('fitted' of the downstream
  benchmark: what a folder of DNGs gives `g2r-fit-profile`);
- the family of the content model is chosen on the training folds only
  (`g2r_jax.downstream.illuminant.content_rows.fold_content_model`, which `g2r-downstream --content-rows`
  uses too): they are split again (two thirds / one third, seeded, duplicate files kept
  together); each candidate family is fitted to the inner two thirds'
  thumbnails (white-balanced by their light, as a DNG's AsShotNeutral would), g2r_jax RAW of the
  CG views is made with it under lights fitted to the same two thirds, the selection estimator is
  trained on it and tested on the inner third; the family with the lowest mean error is kept
  ('identity' is a candidate), then refitted to all training folds' thumbnails. Candidates:
  'chroma' and 'chroma_tone' fitted to the statistics (no labels), 'chroma@S' a given chroma
  scale S (its choice uses the training folds' labels, through the inner third's errors);
- rows: fitted (no content model), fitted+content, upi, upi+content (UPI on the same adapted
  views, re-encoded to sRGB), real (the training folds); each estimator trained on each row and
  tested on the test fold's real images (angular error, degrees). The test images are used for
  nothing else.

    python benchmarks/content_model.py [--cameras Canon600D,NikonD40] [--seeds 1] [--first-seed 0] [--n 300]
        [--estimators cnn,moments] [--families chroma,chroma_tone,chroma@0.5] [--select-estimator moments]
        [--fixed cast@0]
        [--jobs 1] [--json out/content_model.json] [--markdown out/content_model.md]
    python benchmarks/content_model.py --fit-speed 300     # the g2r-fit-profile step's time
    python benchmarks/content_model.py --apply-speed       # unprocess with the model on and off

Data: ../shared/data/estimation/nus/<camera>.npz and ../shared/data/cg/carla/*.png (as
benchmarks/downstream_nus.py, whose camera profiles it uses).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from downstream_nus import CAMERAS, CARLA, NUS, camera_profile  # noqa: E402

ROWS = ("fitted", "fitted+content", "upi", "upi+content", "real")


def _say(message: str) -> None:
    print(f"  {time.strftime('%H:%M:%S')} {message}", file=sys.stderr, flush=True)


def _row_sets(real, train, views, srgb_views, model, fitted, seed, fold):
    from g2r_jax.downstream.base import training_sets
    from g2r_jax.downstream.base.product import adapted_views

    salt = 1000 * seed + 10 * fold + 4
    adapted = adapted_views(model, views, salt + 1)   # the library's draws (`content_rows._adapted`): one implementation
    return {"fitted": lambda: training_sets.g2r_set(views, fitted, salt),
            "fitted+content": lambda: training_sets.g2r_set(adapted, fitted, salt),
            "upi": lambda: training_sets.upi_set(srgb_views, seed + 1),
            "upi+content": lambda: training_sets.upi_set(training_sets.linear_to_srgb_views(adapted), seed + 1),
            "real": lambda: (real.images[train], real.illuminants[train])}


def run_camera(job) -> dict:
    """One camera: errors per (row, estimator) per seed, and the models chosen per fold."""
    from PIL import Image

    from g2r_jax.downstream.base import product, real_sets, training_sets
    from g2r_jax.downstream.illuminant import content_rows
    from g2r_jax.downstream.illuminant.estimators import train_estimator
    from g2r_jax.measure import angular_error_degrees, folds_of
    from g2r_jax.runtime import compile_cache

    compile_cache.enable(program="g2r_jax-downstream")
    name, estimators, seeds, n, families, select_estimator, fixed = job
    start = time.perf_counter()
    linear = training_sets.linear_images([np.asarray(Image.open(f).convert("RGB")) for f in sorted(CARLA.glob("*.png"))])
    real = real_sets.load_nus(NUS / f"{name}.npz")
    profile = camera_profile(name)
    errors = {f"{r}/{e}": [] for r in ROWS for e in estimators}
    chosen = []
    for seed in seeds:
        views = training_sets.cg_views(linear, n, seed)
        srgb_views = training_sets.linear_to_srgb_views(views)
        parts = {key: [] for key in errors}
        for fold, test in enumerate(folds_of(len(real.images), 3, 0, groups=getattr(real, "groups", None))):
            train = np.setdiff1d(np.arange(len(real.images)), test)
            if fixed:
                choice = content_rows.FoldChoice(model=product.candidate_model(
                    fixed, real.images[train], real.illuminants[train], views, profile), name=fixed, errors={})
            else:
                choice = content_rows.fold_content_model(
                    real, train, views, profile, lambda lights: product.fitted_illuminants(profile, lights, "auto", seed),
                    candidates=("identity",) + families, estimator=select_estimator, seed=seed, fold=fold)
            family, selection, model = choice.name, choice.errors, choice.model
            chosen.append({"seed": seed, "fold": fold, "family": family, "selection_errors": selection,
                           "chroma_scale": float(model.chroma_scale), "tone_power": float(model.tone_power),
                           "cast_scale": float(model.cast_scale)})
            fitted = product.fitted_illuminants(profile, real.illuminants[train], "auto", seed)
            for row, build in _row_sets(real, train, views, srgb_views, model, fitted, seed, fold).items():
                images, labels = build()
                for estimator in estimators:
                    predict = train_estimator(estimator, images, labels, seed=1000 * seed + fold)
                    parts[f"{row}/{estimator}"].append(
                        angular_error_degrees(predict(real.images[test]), real.illuminants[test]))
            _say(f"{name}: seed {seed} fold {fold + 1}/3: {family} (s {float(model.chroma_scale):.3f}, "
                 f"p {float(model.tone_power):.3f}, c {float(model.cast_scale):.3f}; selection {selection}) "
                 f"({time.perf_counter() - start:.0f} s)")
        for key, values in parts.items():
            errors[key].append(np.concatenate(values).tolist())
    return {"camera": name, "errors": errors, "chosen": chosen, "seconds": time.perf_counter() - start}


def _mean(result, row, estimator) -> float:
    return float(np.mean(np.concatenate(result["errors"][f"{row}/{estimator}"])))


def tables(results: dict, estimators) -> str:
    """Markdown: per estimator, each camera's mean error per row, the ratios to real training and
    the lead over UPI on the same content; then the mean of cameras."""
    out = []
    for e in estimators:
        out += [f"**{e}** (mean angular error, degrees, pooled over seeds and folds)", "",
                "| camera | " + " | ".join(ROWS) + " | fitted / real | fitted+content / real | "
                "fitted+content vs upi+content | families kept (s, p, c) |", "|---|" + "---|" * (len(ROWS) + 4)]
        means = {name: {r: _mean(res, r, e) for r in ROWS} for name, res in results.items()}
        for name, m in means.items():
            kept = ", ".join(f"{c['family']} ({c['chroma_scale']:.2f}, {c['tone_power']:.2f}, {c.get('cast_scale', 1.0):.2f})"
                             for c in results[name]["chosen"])
            out.append(f"| {name} | " + " | ".join(f"{m[r]:.2f}" for r in ROWS)
                       + f" | {m['fitted'] / m['real']:.2f}x | {m['fitted+content'] / m['real']:.2f}x"
                       + f" | {100 * (1 - m['fitted+content'] / m['upi+content']):+.0f} % | {kept} |")
        mean = {r: float(np.mean([m[r] for m in means.values()])) for r in ROWS}
        out.append("| **mean of cameras** | " + " | ".join(f"{mean[r]:.2f}" for r in ROWS)
                   + f" | {mean['fitted'] / mean['real']:.2f}x | {mean['fitted+content'] / mean['real']:.2f}x"
                   + f" | {100 * (1 - mean['fitted+content'] / mean['upi+content']):+.0f} % | |")
        out.append("")
    return "\n".join(out)


def fit_speed(count: int) -> str:
    """Seconds the content-model step of g2r-fit-profile takes for `count` small DNGs (the CARLA
    frames, 190 x 320, made RAW for Canon600D and written to a temporary folder first)."""
    import tempfile

    import g2r_jax
    from g2r_jax.batch.conversion import ConvertOptions, convert_files
    from g2r_jax.content import content_model_from_files, describe
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
    from g2r_jax.profile.fitting import as_shot_neutral

    frames = sorted(CARLA.glob("*.png"))
    inputs = [frames[i % len(frames)] for i in range(count)]
    with tempfile.TemporaryDirectory() as folder:
        names = [f"frame{i:04d}" for i in range(count)]
        convert_files(inputs, g2r_jax.load_profile("Canon600D"), Path(folder), options=ConvertOptions(seed=0),
                      names=names, write_manifest=False)
        paths = sorted(Path(folder).glob("*.dng"))
        start, cpu = time.perf_counter(), time.process_time()

        def read(path):
            info = read_dng_info(path)
            return read_dng_pixels(path, info), info.cfa_pattern, info.black_level, info.white_level, as_shot_neutral(info)

        model, used = content_model_from_files(paths, read, colour_model=g2r_jax.load_profile("Canon600D").colour)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return (f"content model of {used} DNGs of 190 x 320 (read, thumbnails, statistics, fit): {seconds:.2f} s wall, "
            f"{cpu:.2f} s CPU; {describe(model)}")


def apply_speed(repeats: int = 5) -> str:
    """CPU time of one jitted `unprocess` of a 1000 x 1500 sRGB frame with the content model off,
    on as 'chroma' (folded into the colour matrix), 'chroma_tone' (a pass over the pixels with the
    image's peak), 'cast' (the image's mean, then a diagonal folded into the colour matrix) and
    'scenes' (a power found on the image's grid, then a power and a gain per pixel),
    measured in turns (best of `repeats` per turn after a warm-up)."""
    import jax

    import g2r_jax
    from g2r_jax.content import content_model, prior_cast_model
    from g2r_jax.profile.schema import replace

    base = g2r_jax.load_profile("Canon600D")
    variants = {"off": (base, False), "chroma": (replace(base, content=content_model(0.35)), True),
                "chroma_tone": (replace(base, content=content_model(0.35, 1.3, family="chroma_tone")), True),
                "cast": (replace(base, content=prior_cast_model(base.colour)), True),
                "scenes": (replace(base, content=_speed_scenes_model()), True)}
    image = np.random.default_rng(0).integers(0, 256, (1000, 1500, 3)).astype(np.uint8)
    key = jax.random.PRNGKey(0)
    best = {}
    for _turn in range(2):
        for name, (profile, on) in variants.items():
            run = jax.jit(lambda k, x, p, on=on: g2r_jax.unprocess(k, x, p, content=on)[0])
            run(key, image, profile).block_until_ready()
            for _ in range(repeats):
                cpu = time.process_time()
                run(key, image, profile).block_until_ready()
                best[name] = min(best.get(name, np.inf), time.process_time() - cpu)
    off = best["off"]
    return (f"unprocess of a 1000 x 1500 frame, CPU time (best of {2 * repeats}): content off {1000 * off:.1f} ms, "
            + ", ".join(f"{name} {1000 * best[name]:.1f} ms ({100 * (best[name] / off - 1):+.1f} %)"
                        for name in ("chroma", "chroma_tone", "cast", "scenes")))


def _speed_scenes_model():
    """A 'scenes' model of 64 invented scenes (its cost does not depend on their values)."""
    from g2r_jax.content import content_model
    from g2r_jax.content.scenes import TABLE_SIZE

    rng = np.random.default_rng(0)
    return content_model(family="scenes", scene_casts=rng.uniform(0.8, 1.2, (TABLE_SIZE, 3)),
                         scene_brightness=rng.uniform(0.05, 0.3, TABLE_SIZE))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", default=",".join(CAMERAS))
    parser.add_argument("--estimators", default="cnn,moments")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--first-seed", type=int, default=0, help="seeds first-seed .. first-seed + seeds - 1")
    parser.add_argument("--n", type=int, default=300)
    parser.add_argument("--families", default="chroma,chroma_tone,chroma@0.65,chroma@0.5,chroma@0.35",
                        help="candidates besides 'identity': chroma and chroma_tone fitted from the statistics, "
                        "chroma@S a chroma scale S given")
    parser.add_argument("--select-estimator", default="moments", help="the estimator that chooses the family")
    parser.add_argument("--fixed", default="", metavar="CANDIDATE",
                        help="use this candidate (e.g. cast@0) on every fold, without a selection (no labels used)")
    parser.add_argument("--jobs", type=int, default=1, help="cameras run in this many processes at once")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--markdown", type=Path)
    parser.add_argument("--fit-speed", type=int, metavar="N", help="only time the g2r-fit-profile step on N small DNGs")
    parser.add_argument("--apply-speed", action="store_true", help="only time unprocess with the model on and off")
    args = parser.parse_args(argv)
    if args.apply_speed:
        print(apply_speed())
        return 0
    if args.fit_speed:
        print(fit_speed(args.fit_speed))
        return 0
    if not NUS.is_dir() or not CARLA.is_dir():
        print(f"cannot run: needs {NUS} and {CARLA}", file=sys.stderr)
        return 2
    cameras, estimators = args.cameras.split(","), tuple(args.estimators.split(","))
    seeds = tuple(range(args.first_seed, args.first_seed + args.seeds))
    jobs = [(c, estimators, seeds, args.n, tuple(args.families.split(",")), args.select_estimator,
             args.fixed) for c in cameras]
    start = time.perf_counter()
    results = {}
    if args.jobs > 1:
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(args.jobs) as pool:
            for result in pool.imap(run_camera, jobs):
                results[result["camera"]] = result
    else:
        for job in jobs:
            result = run_camera(job)
            results[result["camera"]] = result
            if args.json:   # what has finished so far, in case the run is cut short
                _write_json(args.json, results, args, time.perf_counter() - start)
    text = tables(results, estimators) + f"\nTotal {(time.perf_counter() - start) / 60:.1f} min.\n"
    print(text)
    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text(text)
    if args.json:
        _write_json(args.json, results, args, time.perf_counter() - start)
    return 0


def _write_json(path: Path, results, args, seconds) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    document = {"seconds": seconds, "n": args.n, "seeds": args.seeds, "families": args.families,
                "select_estimator": args.select_estimator,
                "fixed": args.fixed, "cameras": results}
    temporary = path.with_suffix(".tmp")
    temporary.write_text(json.dumps(document))
    temporary.replace(path)


if __name__ == "__main__":
    sys.exit(main())
