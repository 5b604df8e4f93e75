"""The paper's illuminant-estimation experiment on real images (Graphics2RAW Table 2 / S1 / S4),
for the nine NUS cameras: estimators trained on synthetic RAW of the CARLA CG frames (UPI,
published recipe, g2r_jax shipped / fitted / one DNG), on the real training folds, and on the
controls, tested on the real images of each camera (`g2r_jax.downstream.experiment`).

Data: ../shared/data/estimation/nus/<camera>.npz (real thumbnails, measured illuminants) and
../shared/data/cg/carla/*.png. Profiles: the shipped profile of the camera; Canon1DsMkIII,
FujifilmXM1 and SamsungNX2000 have none: their Adobe ColorMatrix pair from
../shared/data/cameras/color_matrices.json on the Canon600D profile's sensor (levels, noise,
exposure), lights from the cross-camera prior mapped through their matrices (as shipped
profiles without measured lights have them).

    python benchmarks/downstream_nus.py [--cameras Canon600D,NikonD40] [--seeds 3] [--n 1000]
        [--estimators cnn,moments] [--rows ...] [--illuminant-model auto] [--lights 25]
        [--json out/downstream_nus.json] [--markdown out/downstream_nus.md]

Prints one table per camera as it finishes, then the summary across cameras.
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
    """The shipped profile, or the camera's matrix pair on the template's sensor."""
    import g2r_jax
    from g2r_jax.colour.dng_model import DngColourModel
    from g2r_jax.profile.fitting import illuminant_model_for
    from g2r_jax.profile.schema import replace

    if name in g2r_jax.shipped_profiles():
        return g2r_jax.load_profile(name)
    tags = json.loads((DATA / "cameras" / "color_matrices.json").read_text())[name]
    colour = DngColourModel.from_tags((17, 21), (np.reshape(tags["ColorMatrix_StandardLightA_tag17"], (3, 3)),
                                                 np.reshape(tags["ColorMatrix_D65_tag21"], (3, 3))))
    template = g2r_jax.load_profile(TEMPLATE)
    return replace(template, colour=colour, illuminants=illuminant_model_for(np.zeros((0, 2)), colour, "prior"))


def other_camera(name: str, cameras) -> str:
    """The camera whose images are the other-content control: the next one in CAMERAS."""
    index = CAMERAS.index(name)
    return CAMERAS[(index + 1) % len(CAMERAS)]


def main(argv=None) -> int:
    from PIL import Image

    from g2r_jax.downstream import experiment, real_sets, report
    from g2r_jax.runtime import compile_cache

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", default=",".join(CAMERAS))
    parser.add_argument("--rows", default=",".join(experiment.ROWS))
    parser.add_argument("--estimators", default="cnn,moments")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--n", type=int, default=1000)
    parser.add_argument("--illuminant-model", default="auto")
    parser.add_argument("--lights", type=int, help="fit the lights to this many training files only "
                        "(the number-of-DNGs ablation of Table S6)")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--markdown", type=Path)
    args = parser.parse_args(argv)
    if not NUS.is_dir() or not CARLA.is_dir():
        print(f"cannot run: needs {NUS} and {CARLA}", file=sys.stderr)
        return 2
    compile_cache.enable(program="g2r_jax-downstream")
    cameras = args.cameras.split(",")
    rows = args.rows.split(",")
    estimators = tuple(args.estimators.split(","))
    cg = [np.asarray(Image.open(f).convert("RGB")) for f in sorted(CARLA.glob("*.png"))]
    start = time.perf_counter()
    results, lines = {}, []
    for name in cameras:
        real = real_sets.load_nus(NUS / f"{name}.npz")
        profile = camera_profile(name)
        other = None
        if "other_content" in rows:
            partner = other_camera(name, cameras)
            other = (real_sets.load_nus(NUS / f"{partner}.npz"), camera_profile(partner))
        result = experiment.illuminant_experiment(
            real, profile, cg, rows=rows, estimators=estimators, seeds=tuple(range(args.seeds)), n=args.n,
            illuminant_model=args.illuminant_model, lights=args.lights, other=other,
            progress=lambda m: print(f"  {m}", file=sys.stderr, flush=True))
        results[name] = result
        block = [f"## {name} ({len(real.images)} real images; {result.seconds:.0f} s)", "", report.table(result), ""]
        block += [report.sentence(result, e) for e in estimators] + [""]
        print("\n".join(block), flush=True)
        lines += block
    summary = summary_table(results, rows, estimators)
    total = time.perf_counter() - start
    lines += ["## All cameras: mean error (degrees), pooled over seeds", "", summary, "",
              f"Total {total / 60:.1f} min."]
    print("\n".join(lines[-5:]))
    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text("\n".join(lines) + "\n")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        document = {name: {**r.to_dict(), "decomposition": {e: report.decomposition(r, e) for e in estimators}}
                    for name, r in results.items()}
        args.json.write_text(json.dumps({"seconds": total, "n": args.n, "cameras": document}, indent=1))
    return 0


def summary_table(results, rows, estimators) -> str:
    from g2r_jax.downstream.experiment import ROWS

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
