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
then the summary across cameras (`--summary` prints those of earlier runs' JSON files). LibRaw runs single-threaded (OMP_NUM_THREADS=1 unless set):
on 64 x 64 files its threads only wait for each other on a shared 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from downstream_nus import CAMERAS, CARLA, NUS, camera_profile, shipped_content_model  # noqa: E402

ROWS = ("upi", "fitted", "fitted_no_content", "shipped", "single", "real", "real_profile_light")
CURVE_ROWS = ("fitted",)


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


def run_camera(name: str, args, cg, say):
    """{'all': IspResult, 1: IspResult of the curve, ...} of one camera."""
    from g2r_jax.downstream.base import real_sets
    from g2r_jax.downstream.isp import pairs as isp_pairs, task as isp
    from g2r_jax.downstream.isp.net import IspTraining

    real = real_sets.load_nus(NUS / f"{name}.npz")
    profile, shipped = profiles(name)
    dngs = isp_pairs.thumbnail_sources(real.images, real.illuminants, profile, real.files or None)
    masks = None if args.no_masks else isp_pairs.thumbnail_masks(real.images)
    training = IspTraining(steps=args.steps, batch=args.batch, width=args.width, learning_rate=args.learning_rate)
    common = dict(seeds=tuple(range(args.seeds)), folds=3, n=args.n, dngs=dngs, shipped=shipped, training=training,
                  progress=say, masks=masks)
    out = {"all": isp.run_isp_task(real, profile, cg, rows=args.rows, **common)}
    for count in args.lights:
        if count not in (0, None):
            out[count] = isp.run_isp_task(real, profile, cg, rows=CURVE_ROWS, lights=count, **common)
    return out


def _mean(document, camera, part, row, metric):
    """The mean of `metric` for `row` of one camera's run `part` ('all', or a number of lights)."""
    return document[camera][part]["summary"][f"{row}/{metric}"]["mean"]


def summary_table(document) -> str:
    """Markdown: per camera, each row's mean PSNR / SSIM / ΔE2000; then the mean of the cameras,
    the fitted / real ΔE ratio and the PSNR gaps. `document`: {camera: {'all': IspResult.to_dict()}}."""
    rows = next(iter(document.values()))["all"]["rows"]
    head = "| camera | " + " | ".join(rows) + " | fitted / real ΔE | real - fitted PSNR | fitted - UPI PSNR |"
    out = ["Cells: PSNR dB / SSIM / ΔE2000, mean over images, folds and seeds.", "", head,
           "|---|" + "---|" * (len(rows) + 3)]
    value = {}
    for camera in document:
        for r in rows:
            for m in ("psnr", "ssim", "delta_e"):
                value[(camera, r, m)] = _mean(document, camera, "all", r, m)
    for camera in list(document) + ["**mean of cameras**"]:
        get = ((lambda r, m, c=camera: value[(c, r, m)]) if camera in document
               else (lambda r, m: float(np.mean([value[(c, r, m)] for c in document]))))
        cells = [f"{get(r, 'psnr'):.2f} / {get(r, 'ssim'):.3f} / {get(r, 'delta_e'):.2f}" for r in rows]
        out.append(f"| {camera} | " + " | ".join(cells) + " | " + _ratios(get, rows) + " |")
    return "\n".join(out)


def _ratios(value, rows) -> str:
    cells = []
    if {"fitted", "real"} <= set(rows):
        cells += [f"{value('fitted', 'delta_e') / value('real', 'delta_e'):.2f}x",
                  f"{value('real', 'psnr') - value('fitted', 'psnr'):+.2f} dB"]
    else:
        cells += ["", ""]
    cells.append(f"{value('fitted', 'psnr') - value('upi', 'psnr'):+.2f} dB" if {"fitted", "upi"} <= set(rows) else "")
    return " | ".join(cells)


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
    from g2r_jax.downstream.isp.net import IspTraining

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", default=",".join(CAMERAS))
    parser.add_argument("--rows", default=",".join(ROWS))
    parser.add_argument("--seeds", type=int, default=3)
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
    parser.add_argument("--json", type=Path, help="results, rewritten after each camera; a camera already in it "
                                                  "(from a stopped run with the same file) is not run again")
    parser.add_argument("--markdown", type=Path)
    parser.add_argument("--figures", type=Path, help="a folder: one PNG of predictions per camera")
    parser.add_argument("--summary", help="comma-separated JSON files of earlier runs: print their tables, run nothing")
    args = parser.parse_args(argv)
    args.rows = tuple(args.rows.split(","))
    args.lights = [None if v == "all" else int(v) for v in args.lights.split(",") if v]
    return args


def _document(results) -> dict:
    return {name: {str(k): r.to_dict() for k, r in parts.items()} for name, parts in results.items()}


def _write(args, document, lines, total) -> None:
    """The markdown and JSON of the cameras done so far (rewritten after each camera)."""
    from g2r_jax.io.atomic import atomic_write_bytes

    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(args.markdown, ("\n".join(lines) + "\n").encode())
    if args.json:       # atomic: a run stopped while writing leaves the last complete file to resume from
        args.json.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(args.json, json.dumps({"seconds": total, "arguments": {k: str(v) for k, v in vars(args).items()},
                                                  "cameras": document}, indent=1).encode())


def _closing(args, document, total) -> list:
    lines = ["## All cameras", "", summary_table(document), ""]
    if all({"fitted", "upi", "real"} <= set(document[camera]["all"]["rows"]) for camera in document):
        lines += ["## The issue's targets", "", targets_table(document), ""]
    else:
        lines += ["(the issue's targets need the rows fitted, upi and real: not all ran)", ""]
    if args.lights:
        lines += ["## Number of DNGs (PSNR dB / ΔE2000)", "", curve_table(document, args.lights), ""]
    return lines + [f"Total {total / 60:.1f} min; UNet width {args.width}, {args.steps} steps of {args.batch}, "
                    f"learning rate {args.learning_rate:g}; n = {args.n}; seeds 0-{args.seeds - 1}."]


def _summary(args) -> int:
    """Print the tables of earlier runs' JSON files (cameras merged, a later file winning)."""
    document, seconds = {}, 0.0
    for path in args.summary.split(","):
        loaded = json.loads(Path(path).read_text())
        document.update(loaded["cameras"])
        seconds += loaded["seconds"]
    print("\n".join(_closing(args, document, seconds)))
    return 0


def main(argv=None) -> int:
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
    cg = [np.asarray(Image.open(f).convert("RGB")) for f in sorted(CARLA.glob("*.png"))]
    say = lambda m: print(f"  {m}", file=sys.stderr, flush=True)
    start = time.perf_counter()
    results, lines, earlier = {}, [], _earlier(args)
    for name in args.cameras.split(","):
        if name in earlier:
            say(f"{name}: kept from {args.json}")
            lines += [f"## {name} (from the earlier run in {args.json.name})", ""]
            continue
        results[name] = run_camera(name, args, cg, say)
        result = results[name]["all"]
        block = [f"## {name} ({result.images} real images; {result.seconds:.0f} s)", "", result.table(), "",
                 result.sentence(), ""]
        print("\n".join(block), flush=True)
        lines += block
        if args.figures:
            args.figures.mkdir(parents=True, exist_ok=True)
            result.figure(args.figures / f"isp_{name}.png")
        elapsed = time.perf_counter() - start
        document = {**earlier, **_document(results)}
        _write(args, document, lines + _closing(args, document, elapsed), elapsed)
    total = time.perf_counter() - start
    document = {**earlier, **_document(results)}
    closing = _closing(args, document, total)
    print("\n".join(closing))
    _write(args, document, lines + closing, total)
    return 0


def _earlier(args) -> dict:
    """The cameras of an earlier run's --json file (a stopped run resumes after them), else {}."""
    if not args.json or not args.json.is_file():
        return {}
    try:
        return dict(json.loads(args.json.read_text()).get("cameras", {}))
    except (OSError, ValueError) as error:
        print(f"  {args.json}: not read ({error}); every camera runs", file=sys.stderr)
        return {}


if __name__ == "__main__":
    sys.exit(main())
