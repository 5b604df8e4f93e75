"""The paper's neural-ISP task (Graphics2RAW supplement S1.3, Tables S2, S5, S6) on the nine NUS
cameras: a UNet learns packed RAW -> display sRGB (the target: LibRaw at each DNG's as-shot white
balance, `g2r_jax.io.reference_render`) on synthetic pairs made from the CARLA CG frames
(UPI, g2r_jax fitted / without content model / shipped / one DNG) or on the real training folds,
and is tested on the real held-out fold (`g2r_jax.downstream.isp.task.run_isp_task`).

Real pairs: each camera's 64 x 64 NUS thumbnails (../shared/data/estimation/nus/<camera>.npz)
written as 64 x 64 Bayer DNGs of the camera by our own writer (`isp_pairs.thumbnail_sources`:
mosaicked at the profile's CFA, scaled to its black..white levels, saturated pixels (0 in the
npz) white, AsShotNeutral the measured light, the matrices of `downstream_nus.camera_profile`).
CG: ../shared/data/cg/carla/*.png. Profiles as benchmarks/downstream_nus.py: 'fitted' fits the
'cast' content model on the training folds, 'shipped' is the profile with the content model a
shipped profile carries (`shipped_content_model`, applied by default).

    python benchmarks/downstream_isp_nus.py [--cameras Canon600D,NikonD40] [--seeds 3] [--n 200]
        [--rows upi,fitted,...] [--steps 600] [--lights 0,1,10,all] [--json out/isp_nus.json]
        [--markdown out/isp_nus.md] [--figures out/isp_figures]
    python benchmarks/downstream_isp_nus.py --summary out/a.json,out/b.json [--lights 0,1,10,all]

`--lights` adds the few-DNG curve (Table S6): 'fitted' with its lights fitted to 1 or 10 random
training files (content model as in 'fitted'; without a run for 1, the curve's 1 is the 'single'
row: the light and content of one file), 0 = the shipped profile's lights and content
model (the 'shipped' row), all = the 'fitted' row. Prints one table per camera as it finishes,
then the summary across cameras (`--summary` prints those of earlier runs' JSON files, merged by
camera, run and row: a later file wins for a row both hold). The loop over cameras, the JSON and
markdown rewritten after each camera and the resume from --json are `downstream_runner.py`'s.
LibRaw runs single-threaded (OMP_NUM_THREADS=1 unless set):
on 64 x 64 files its threads only wait for each other on a shared 2-core machine.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
import isp_diagnoses  # noqa: E402
import downstream_runner as runner  # noqa: E402
from downstream_nus import CAMERAS, CARLA, NUS, camera_profile, shipped_content_model  # noqa: E402

ROWS = ("upi", "fitted", "fitted_no_content", "shipped", "single", "real", "real_profile_light")
CURVE_ROWS = ("fitted",)
METRICS = ("psnr", "ssim", "delta_e")     # the summary table's cells


def profiles(name: str):
    """(the camera's profile without content model, the same with the shipped content model
    applied by default: the 'shipped' row)."""
    from g2r_jax.content.model import with_default
    from g2r_jax.profile.schema import replace

    profile = camera_profile(name)
    return profile, replace(profile, content=with_default(shipped_content_model(name, profile.colour), True))


def content_part(part: str) -> None:
    """A diagnosis of the 'scenes' content model (issue 47), not a product setting: the ISP rows'
    fitted model keeps only its cast spread ('cast-spread': every scene's brightness 1, which no
    frame is darkened to) or only its brightness ('brightness': every scene's cast the median one
    of the 'cast' model fitted to the same files)."""
    from g2r_jax import content
    from g2r_jax.downstream.base import product

    fitted = product.candidate_model

    def variant(name, images, lights, views, profile):
        model = fitted(name, images, lights, views, profile)
        if model.family != "scenes":
            return model
        casts, brightness = np.asarray(model.scene_casts), np.asarray(model.scene_brightness)
        if part == "cast-spread":
            brightness = np.ones_like(brightness)
        else:
            casts = np.tile(np.asarray(fitted("cast", images, lights, views, profile).cast_target), (len(casts), 1))
        return content.content_model(family="scenes", scene_casts=casts, scene_brightness=brightness,
                                     source=f"{model.source} ({part} only)")

    product.candidate_model = variant


def inner_set(real):
    """The real set without the files of its first outer test fold (`measure.folds_of(N, 3, 0)`'s
    fold 0, the benchmark's own folds): a run on it chooses without ever reading those files."""
    import dataclasses

    from g2r_jax.measure import folds_of

    kept = np.setdiff1d(np.arange(len(real.images)), folds_of(len(real.images), 3, 0, groups=real.groups)[0])
    return dataclasses.replace(real, images=real.images[kept], illuminants=real.illuminants[kept],
                               files=tuple(np.asarray(real.files, object)[kept]) if real.files else (),
                               groups=None if real.groups is None else np.asarray(real.groups)[kept])


def run_camera(name: str, args, cg, say):
    """{'all': IspResult, 1: IspResult of the curve, ...} of one camera."""
    from g2r_jax.downstream.base import real_sets
    from g2r_jax.downstream.isp import pairs as isp_pairs, task as isp
    from g2r_jax.downstream.isp.net import IspTraining

    real = real_sets.load_nus(NUS / f"{name}.npz")
    if args.inner:
        real = inner_set(real)
    profile, shipped = profiles(name)
    written = isp_diagnoses.fill_missing(real.images) if args.real_fill == "mean" else real.images
    dngs = isp_pairs.thumbnail_sources(written, real.illuminants, profile, real.files or None)
    masks = None if args.no_masks else isp_pairs.thumbnail_masks(real.images)
    training = IspTraining(steps=args.steps, batch=args.batch, width=args.width, learning_rate=args.learning_rate)
    common = dict(seeds=tuple(range(args.seeds)), folds=3, n=args.n, dngs=dngs, shipped=shipped, training=training,
                  progress=say, masks=masks, texture=not (args.no_texture or args.texture))
    out = {"all": isp.run_isp_task(real, profile, cg, rows=args.rows, **common)}
    for count in args.lights:
        if count not in (0, None):
            out[count] = isp.run_isp_task(real, profile, cg, rows=CURVE_ROWS, lights=count, **common)
    return out


def _mean(document, camera, part, row, metric):
    """The mean of `metric` for `row` of one camera's run `part` ('all', or a number of lights)."""
    return document[camera][part]["summary"][f"{row}/{metric}"]["mean"]


def _rows(document) -> list:
    """The rows of the cameras' 'all' runs, each once (`downstream_runner.merged_order`)."""
    return runner.merged_order(*(parts["all"]["rows"] for parts in document.values()))


def summary_table(document) -> str:
    """Markdown: per camera, each row's mean PSNR / SSIM / ΔE2000 (empty where the camera lacks the
    row); then the mean of the cameras that hold each row, the fitted / real ΔE ratio and the PSNR
    gaps (on the rows every camera of the line holds). `document`: {camera: {'all': IspResult.to_dict()}}."""
    rows = _rows(document)
    head = "| camera | " + " | ".join(rows) + " | fitted / real ΔE | real - fitted PSNR | fitted - UPI PSNR |"
    out = ["Cells: PSNR dB / SSIM / ΔE2000, mean over images, folds and seeds.", "", head,
           "|---|" + "---|" * (len(rows) + 3)]
    value = {(camera, r, m): _mean(document, camera, "all", r, m)
             for camera in document for r in document[camera]["all"]["rows"] for m in METRICS}
    for camera in list(document) + ["**mean of cameras**"]:
        cameras = [camera] if camera in document else list(document)
        means = _means_over(value, cameras, rows)
        get = lambda r, m, means=means: means[(r, m)]
        cells = [f"{get(r, 'psnr'):.2f} / {get(r, 'ssim'):.3f} / {get(r, 'delta_e'):.2f}" if (r, "psnr") in means
                 else "" for r in rows]
        everywhere = [r for r in rows if all((c, r, "psnr") in value for c in cameras)]
        out.append(f"| {camera} | " + " | ".join(cells) + " | " + _ratios(get, everywhere) + " |")
    return "\n".join(out)


def _means_over(value, cameras, rows) -> dict:
    """{(row, metric): mean over those of `cameras` that hold the row} of `value` {(camera, row, metric): mean}."""
    means = {}
    for r in rows:
        for m in METRICS:
            held = [value[(c, r, m)] for c in cameras if (c, r, m) in value]
            if held:
                means[(r, m)] = float(np.mean(held))
    return means


def _ratios(value, rows) -> str:
    """The cells fitted / real ΔE, real - fitted PSNR and fitted - UPI PSNR (empty without those rows)."""
    cells = []
    if {"fitted", "real"} <= set(rows):
        cells += [f"{value('fitted', 'delta_e') / value('real', 'delta_e'):.2f}x",
                  f"{value('real', 'psnr') - value('fitted', 'psnr'):+.2f} dB"]
    else:
        cells += ["", ""]
    cells.append(f"{value('fitted', 'psnr') - value('upi', 'psnr'):+.2f} dB" if {"fitted", "upi"} <= set(rows) else "")
    return " | ".join(cells)


def parts_table(document) -> str:
    """Markdown: per row, the mean over cameras of ΔE2000 and of what is left after each test
    image's best gains and best 3 x 3 matrix (`isp.error_parts`; runs that stored them)."""
    from g2r_jax.downstream.isp.task import ROWS as NAMES

    held = {c: parts["all"]["summary"] for c, parts in document.items()}
    out = ["| training set | cameras | ΔE2000 | after best gains | after best 3 x 3 | white balance's share |",
           "|---|---|---|---|---|---|"]
    for row in _rows(document):
        cameras = [c for c, s in held.items() if f"{row}/delta_e_balance" in s]
        if not cameras:
            continue
        e, g, m = (float(np.mean([held[c][f"{row}/{k}"]["mean"] for c in cameras]))
                   for k in ("delta_e", "delta_e_balance", "delta_e_colour"))
        out.append(f"| {NAMES.get(row, row)} (`{row}`) | {len(cameras)} | {e:.2f} | {g:.2f} | {m:.2f} | {(e - g) / e:.0%} |")
    return "\n".join(out)


def curve_table(document, lights) -> str:
    """Markdown: the few-DNG curve, PSNR / ΔE2000 of g2r_jax by the number of DNGs its lights come
    from (mean over seeds), per camera and the mean of the cameras."""
    labels = [("0 (shipped)" if c == 0 else "all" if c is None else str(c)) for c in lights]
    out = ["| camera | " + " | ".join(f"{label} DNGs" for label in labels) + " |", "|---|" + "---|" * len(lights)]
    columns = {label: [] for label in labels}
    for camera, parts in document.items():
        cells = []
        for count, label in zip(lights, labels):
            part, row = ("all", "shipped") if count == 0 else ("all", "fitted") if count is None else (str(count), "fitted")
            if count == 1 and part not in parts and "single" in parts["all"]["rows"]:
                part, row = "all", "single"      # one DNG: g2r-fit-profile on one file (its light and content)
            if part not in parts or row not in parts[part]["rows"]:
                cells.append("")
                continue
            pair = (_mean(document, camera, part, row, "psnr"), _mean(document, camera, part, row, "delta_e"))
            columns[label].append(pair)
            cells.append(f"{pair[0]:.2f} / {pair[1]:.2f}")
        out.append(f"| {camera} | " + " | ".join(cells) + " |")
    out.append("| **mean** | " + " | ".join(f"{np.mean([p[0] for p in v]):.2f} / {np.mean([p[1] for p in v]):.2f}"
                                         if v else "" for v in columns.values()) + " |")
    return "\n".join(out)


def targets_table(document) -> str:
    """Markdown: the issue's done-when checks per camera (fitted against UPI: the difference of the
    means, and whether the seeds' ranges are apart) and on the mean of the cameras."""
    def apart(camera, metric):
        f = document[camera]["all"]["summary"][f"fitted/{metric}"]
        u = document[camera]["all"]["summary"][f"upi/{metric}"]
        return f["seed_min"] > u["seed_max"] if metric == "psnr" else f["seed_max"] < u["seed_min"]

    out = ["| camera | fitted - UPI PSNR | seeds apart | fitted / UPI ΔE | seeds apart | fitted / real ΔE | "
           "real - fitted PSNR | shipped / real ΔE |", "|---|---|---|---|---|---|---|---|"]
    for camera in document:
        v = lambda r, m: _mean(document, camera, "all", r, m)
        out.append(f"| {camera} | {v('fitted', 'psnr') - v('upi', 'psnr'):+.2f} dB | {'yes' if apart(camera, 'psnr') else 'no'} | "
                   f"{v('fitted', 'delta_e') / v('upi', 'delta_e'):.2f}x | {'yes' if apart(camera, 'delta_e') else 'no'} | "
                   f"{v('fitted', 'delta_e') / v('real', 'delta_e'):.2f}x | {v('real', 'psnr') - v('fitted', 'psnr'):+.2f} dB | "
                   + (f"{v('shipped', 'delta_e') / v('real', 'delta_e'):.2f}x |" if "shipped" in document[camera]["all"]["rows"]
                      else " |"))
    return "\n".join(out)


def _arguments(argv):
    """The command line: the runner's shared arguments, then this benchmark's own."""
    from g2r_jax.downstream.isp.net import IspTraining

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    runner.add_arguments(parser, CAMERAS)
    parser.add_argument("--rows", default=",".join(ROWS))
    parser.add_argument("--n", type=int, default=200, help="synthetic training pairs per set")
    parser.add_argument("--steps", type=int, default=IspTraining.steps)
    parser.add_argument("--batch", type=int, default=IspTraining.batch)
    parser.add_argument("--width", type=int, default=IspTraining.width)
    parser.add_argument("--learning-rate", type=float, default=IspTraining.learning_rate)
    parser.add_argument("--lights", default="", help="the few-DNG curve, e.g. 0,1,10,all")
    parser.add_argument("--no-masks", action="store_true",
                        help="measure and train on every pixel, the thumbnails' masked chart and saturated pixels "
                             "(written white) included: the protocol before the masks")
    parser.add_argument("--content-part", choices=("cast-spread", "brightness"),
                        help="diagnosis: the 'scenes' model's cast spread or brightness alone (content_part)")
    parser.add_argument("--control-light", choices=("drawn", "own"), default="drawn",
                        help="diagnosis: the control row's scenes under their own measured lights (isp_diagnoses)")
    parser.add_argument("--control-exposure", choices=("drawn", "own"), default="drawn",
                        help="diagnosis: each control pair's level set to its real pair's (isp_diagnoses)")
    parser.add_argument("--metered-exposure", action="store_true",
                        help="diagnosis: every g2r_jax pair's level drawn from the real training pairs' (isp_diagnoses)")
    parser.add_argument("--joint-scenes", action="store_true",
                        help="diagnosis: each 'fitted' view takes one training file's cast and its light (isp_diagnoses)")
    parser.add_argument("--inner", action="store_true",
                        help="choose on training data only: leave out the files of the first outer test fold, "
                             "run the 3 folds on the rest (inner_set)")
    parser.add_argument("--no-texture", action="store_true",
                        help="the g2r_jax rows' CG views without their files' texture (content.texture): as before issue 49's change")
    parser.add_argument("--cast-only", action="store_true",
                        help="diagnosis: the g2r_jax rows take a 'scenes' model's median cast even with the texture (isp_diagnoses)")
    parser.add_argument("--texture-after", action="store_true",
                        help="diagnosis: the texture drawn after the content model, not before it (isp_diagnoses)")
    parser.add_argument("--texture-scale", type=float, default=1.0,
                        help="the g2r_jax rows' texture with its standard deviations times this (isp_diagnoses.texture_scale)")
    parser.add_argument("--texture", choices=("real", "noise"),
                        help="diagnosis: every g2r_jax view (and UPI's) times the texture of a real training thumbnail "
                             "('real') or a draw of their texture's covariance ('noise') (isp_diagnoses)")
    parser.add_argument("--real-fill", choices=("white", "mean"), default="white",
                        help="diagnosis: the thumbnails' missing pixels written as the image's mean colour (isp_diagnoses)")
    parser.add_argument("--figures", type=Path, help="a folder: one PNG of predictions per camera")
    args = parser.parse_args(argv)
    args.rows = tuple(args.rows.split(","))
    args.lights = [None if v == "all" else int(v) for v in args.lights.split(",") if v]
    return args


def camera_entry(results) -> dict:
    """One camera's JSON entry: {'all': IspResult.to_dict(), '10': ..., ...}."""
    return {str(k): r.to_dict() for k, r in results.items()}


def camera_lines(args, name: str, results) -> list:
    """The markdown block of a camera run now (its 'all' run's table and sentence); its figure
    with --figures."""
    result = results["all"]
    if args.figures:
        args.figures.mkdir(parents=True, exist_ok=True)
        result.figure(args.figures / f"isp_{name}.png")
    return [f"## {name} ({result.images} real images; {result.seconds:.0f} s)", "", result.table(), "",
            result.sentence(), "", "Where the colour error lies (`error_parts`):", "", result.parts_table(), ""]


def _closing(args, document, total) -> list:
    """The markdown after the cameras: the summary, the issue's targets, the few-DNG curve with
    --lights, the settings."""
    lines = ["## All cameras", "", summary_table(document), ""]
    if all({"fitted", "upi", "real"} <= set(document[camera]["all"]["rows"]) for camera in document):
        lines += ["## The issue's targets", "", targets_table(document), ""]
    else:
        lines += ["(the issue's targets need the rows fitted, upi and real: not all ran)", ""]
    parts = parts_table(document)
    if parts.count("\n") > 1:
        lines += ["## Where the colour error lies (mean of the cameras)", "", parts, ""]
    if args.lights:
        lines += ["## Number of DNGs (PSNR dB / ΔE2000)", "", curve_table(document, args.lights), ""]
    return lines + [f"Total {total / 60:.1f} min; UNet width {args.width}, {args.steps} steps of {args.batch}, "
                    f"learning rate {args.learning_rate:g}; n = {args.n}; seeds 0-{args.seeds - 1}."]


def _summary(args) -> int:
    """Print the tables of earlier runs' JSON files (merged by camera, run and row, a later file winning)."""
    paths = args.summary.split(",")
    document, seconds = runner.read_runs(paths, nesting=2)
    if not document:
        print("no results in " + ", ".join(paths), file=sys.stderr)
        return 2
    print("\n".join(_closing(args, document, seconds)))
    return 0


def main(argv=None) -> int:
    """Run the cameras (or print --summary); 0 when done, 2 without the data."""
    from PIL import Image

    from g2r_jax.runtime import compile_cache

    args = _arguments(argv)
    if args.summary:
        return _summary(args)
    if not NUS.is_dir() or not CARLA.is_dir():
        print(f"cannot run: needs {NUS} and {CARLA}", file=sys.stderr)
        return 2
    compile_cache.enable(program="g2r_jax-downstream")
    if args.content_part:
        content_part(args.content_part)
    if (args.control_light, args.control_exposure) != ("drawn", "drawn"):
        isp_diagnoses.control_variant(args.control_light, args.control_exposure)
    if args.metered_exposure:
        isp_diagnoses.metered_exposure()
    if args.joint_scenes:
        isp_diagnoses.joint_scenes()
    if args.texture:
        isp_diagnoses.textured(args.texture)
    if args.cast_only:
        isp_diagnoses.cast_only()
    if args.texture_after:
        isp_diagnoses.texture_after()
    if args.texture_scale != 1.0:
        isp_diagnoses.texture_scale(args.texture_scale)
    cg = [np.asarray(Image.open(f).convert("RGB")) for f in sorted(CARLA.glob("*.png"))]
    benchmark = runner.CameraBenchmark(
        run=lambda name: run_camera(name, args, cg, runner.say), entry=camera_entry,
        camera_lines=lambda name, results: camera_lines(args, name, results),
        kept_lines=lambda name, entry: [f"## {name} (from the earlier run in {args.json.name})", ""],
        closing_lines=lambda document, seconds: _closing(args, document, seconds),
        header=lambda seconds: {"seconds": seconds, "arguments": {k: str(v) for k, v in vars(args).items()}},
        indent=1)
    runner.run_cameras(benchmark, {name: name for name in args.cameras.split(",")}, json_path=args.json,
                       markdown_path=args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
