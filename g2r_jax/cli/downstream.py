"""g2r-downstream: does a network trained on g2r_jax RAW of your CG images work on your camera?

Parses the arguments and calls `g2r_jax.downstream.run_check` (the illuminant estimators on real
DNGs, the controls that split the gap, optionally the denoising check on a burst) and
`g2r_jax.downstream.write_report`.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from g2r_jax.cli.common import (add_common_flags, command_parser, one_line, output_folder_problem, required_group,
                                run_command)

EXAMPLES = """  g2r-downstream --measured my_camera_dngs/ --cg renders/ --report downstream/
  g2r-downstream --measured my_camera_dngs/ --cg renders/ --profile my_camera.json --report downstream/ --seeds 3
  g2r-downstream --measured dngs/ --cg renders/ --burst burst_dngs/ --report downstream/
  g2r-downstream --burst burst_dngs/ --report denoising/
"""
DEFAULT_ESTIMATORS = "cnn,histogram"
ESTIMATOR_NAMES = ("cnn", "moments", "histogram")   # `downstream.illuminant.estimators.ESTIMATORS`, without loading JAX
TASK_NAMES = ("colour", "isp")                     # `downstream.check.TASKS`
LIMITS = {"seeds": (1, 100), "n": (50, 100_000), "folds": (2, 50), "denoiser_steps": (1, 1_000_000)}


def _parser() -> argparse.ArgumentParser:
    parser = command_parser(
        "g2r-downstream",
        "Train illuminant estimators on synthetic RAW made from your CG images (g2r_jax as "
        "g2r-fit-profile makes it, without its content model as a control, and UPI), on "
        "your real DNGs (cross-validated) and on controls; test them on your real DNGs (labelled by "
        "their AsShotNeutral, the camera's own white balance) and say how much of the gap to real "
        "training is the profile and how much the CG content. With --burst, also (or only) the "
        "denoising check.", EXAMPLES)
    required = required_group(parser)
    required.add_argument("--report", required=True, metavar="DIR",
                          help="folder for report.json, report.md and the plot (created if missing; not an input "
                               "folder)")
    parser.add_argument("--measured", nargs="+", metavar="DNG_DIR",
                        help="folders or files of real DNGs of one camera, shot under several lights (at least 12 "
                             "usable files); needs --cg")
    parser.add_argument("--cg", nargs="+", metavar="IMAGE_DIR",
                        help="folders or files of CG images (PNG, JPEG, TIFF sRGB; EXR linear), each at least "
                             "128 pixels on its shorter side")
    parser.add_argument("--profile", metavar="NAME|FILE",
                        help="the camera's sensor profile (default: fitted from the measured DNGs, or the burst's, "
                             "as g2r-fit-profile would, with its content model fitted per fold on the training "
                             "folds; a given profile's lights are refitted per fold, its content model kept)")
    parser.add_argument("--burst", metavar="DNG_DIR",
                        help="the denoising check: a folder of DNGs of one static scene (>= 3 frames); alone, "
                             "or with --measured and --cg")
    parser.add_argument("--denoiser-steps", type=int, metavar="STEPS",
                        help="Adam steps per denoiser training of the burst check (default: chosen on a validation "
                             "split of the burst, where the real pairs' error stops improving, at most 3000)")
    parser.add_argument("--estimators", default=DEFAULT_ESTIMATORS,
                        help="comma-separated, of cnn, moments, histogram")
    parser.add_argument("--seeds", type=int, default=2, help="repetitions with new synthetic sets")
    parser.add_argument("--n", type=int, default=600, help="synthetic training images per set")
    parser.add_argument("--folds", type=int, default=3, help="cross-validation folds of the real files")
    parser.add_argument("--tasks", default="colour", metavar="TASKS",
                        help="comma-separated, what the real DNGs test: colour (illuminant estimators), isp (a small "
                             "UNet learning RAW -> sRGB, the target developed by LibRaw at each file's AsShotNeutral; "
                             "adds a few minutes, so not in the default)")
    parser.add_argument("--content-rows", action="store_true",
                        help="add a row: UPI on the same content-adapted CG images as the g2r_jax row (one more "
                             "training set per fold and seed, trained with every estimator): g2r_jax's lead over "
                             "UPI on equal content")
    parser.add_argument("--curve", default="", metavar="COUNTS",
                        help="comma-separated numbers of labelled real files, e.g. 10,30,100: also train the "
                             "estimators on only that many of the training files, alone and with g2r_jax RAW, "
                             "and draw what adding g2r_jax RAW is worth by the number of files (augmentation.png)")
    parser.add_argument("--no-cache", action="store_true",
                        help="train everything again: do not read or write the store of finished trainings (by "
                             "default a second run on the same inputs, or one adding rows, reuses them; kept in "
                             "~/.cache/g2r_jax/downstream or $G2R_JAX_DOWNSTREAM_CACHE, at most 512 MB)")
    parser.add_argument("--max-megapixels", type=float, default=100.0, metavar="MPX",
                        help="refuse CG images larger than this (0: no limit)")
    parser.add_argument("--dry-run", action="store_true",
                        help="read and check every input, the profile and the report folder, say what would be "
                             "used and left out; train nothing and write no report")
    add_common_flags(parser)
    return parser


def _range_problem(args) -> str | None:
    for name, (low, high) in LIMITS.items():
        value = getattr(args, name)
        if value is not None and not low <= value <= high:
            shown = str(value) if len(str(value)) <= 20 else f"{str(value)[:12]}... ({len(str(value))} digits)"
            return f"--{name.replace('_', '-')} {shown}: must be from {low} to {high}"
    if not 0 <= args.max_megapixels < float("inf"):
        return f"--max-megapixels {args.max_megapixels}: must be a number >= 0 (0: no limit)"
    return None


def _inputs_problem(args) -> str | None:
    if not args.measured and not args.burst:
        return "nothing to check: give --measured with --cg (the colour check), --burst (the denoising check), or both"
    if args.measured and not args.cg:
        return "--measured needs --cg: the colour check trains on synthetic RAW of CG images"
    for option, items in (("--measured", args.measured or ()), ("--cg", args.cg or ())):
        for item in items:
            problem = _path_problem(option, item)
            if problem:
                return problem
    return _path_problem("--burst", args.burst, folder=True) if args.burst is not None else None


def _curve_problem(curve: str) -> str | None:
    if not curve:
        return None
    parts = curve.split(",")
    if not all(p.strip().isdigit() and 0 < int(p) <= 100_000 for p in parts):
        return f"--curve {curve}: expected comma-separated numbers of files from 1 to 100000, e.g. 10,30,100"
    return None


def _path_problem(option: str, item: str, folder: bool = False) -> str | None:
    try:
        found = Path(item).is_dir() if folder else Path(item).exists()
    except OSError as error:   # a name too long for the system, ...: the reason first, the long name last
        return f"{option}: cannot use the path ({error.strerror or error}): {item}"
    return None if found else f"{option} {item}: no such folder" + ("" if folder else " or file")


def report_folder_problem(args) -> str | None:
    """Why the report cannot go to `args.report`: empty, an input folder or inside one, or not
    writable (tried by creating and removing a probe file, and any folders made for it)."""
    try:
        return _report_folder_problem(args)
    except OSError as error:   # a name too long, a path through a file: the system's own words
        return f"--report: cannot use the path ({error.strerror or error}): {args.report}"


def _report_folder_problem(args) -> str | None:
    import tempfile

    if not args.report.strip():
        return f"--report {args.report!r}: empty; give the folder for the report"
    report = Path(os.path.realpath(args.report))
    inputs = [("--measured", m) for m in args.measured or ()] + [("--cg", c) for c in args.cg or ()]
    inputs += [("--burst", args.burst)] if args.burst else []
    for option, item in inputs:
        folder = Path(os.path.realpath(item))
        if Path(item).is_dir() and (report == folder or folder in report.parents):
            return (f"--report {args.report}: is the input folder {option} {item}" if report == folder else
                    f"--report {args.report}: is inside the input folder {option} {item}") + "; give another folder"
    problem = output_folder_problem("--report", Path(args.report))
    if problem:
        return problem
    made = [p for p in [report, *report.parents] if not p.exists()]
    try:
        report.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=report, prefix=".g2r-probe-"):
            pass
    except OSError as error:
        return f"--report {args.report}: cannot write there ({error.strerror or error})"
    finally:
        for folder in made:   # the deepest first: leave no empty folder behind
            try:
                folder.rmdir()
            except FileNotFoundError:
                continue
            except OSError:
                break
    return None


def check_arguments(args) -> str | None:
    """The first problem found without reading any input file and before JAX is imported (None
    when there is none)."""
    from g2r_jax.profile.shipped import UnknownProfile, profile_path

    problem = _inputs_problem(args) or _range_problem(args) or _curve_problem(args.curve)
    if problem:
        return problem
    tasks = args.tasks.split(",")
    if not args.tasks or any(t not in TASK_NAMES for t in tasks):
        return f"--tasks {args.tasks}: expected some of {', '.join(TASK_NAMES)}"
    unknown = [e for e in args.estimators.split(",") if e not in ESTIMATOR_NAMES]
    if unknown or not args.estimators:
        return f"--estimators {args.estimators}: expected some of {', '.join(ESTIMATOR_NAMES)}"
    if args.profile is not None:
        try:
            profile_path(args.profile)
        except UnknownProfile as error:
            return f"--profile {error}"
    return report_folder_problem(args)


def _run(args) -> int:
    from g2r_jax.downstream import default_rows, run_check, write_report
    from g2r_jax.downstream.base.cache import DownstreamCache, default_location
    from g2r_jax.downstream.base.progress import Progress

    def line(message):
        print(f"g2r-downstream: {message}", file=sys.stderr)

    say = None if args.quiet else Progress(line, desc="g2r-downstream", bar=not args.dry_run)

    def bad(path, reason):
        (say or line)(f"error: {one_line(f'{path}: {reason}')}")

    try:
        result = run_check(args.measured or (), args.cg or (), burst=args.burst, profile=args.profile,
                           estimators=tuple(args.estimators.split(",")), seeds=args.seeds, n=args.n, folds=args.folds,
                           rows=default_rows(args.profile is not None, content_rows=True) if args.content_rows else None,
                           denoiser_steps=args.denoiser_steps, tasks=tuple(args.tasks.split(",")),
                           dry_run=args.dry_run, progress=say, on_problem=bad,
                           curve=tuple(int(c) for c in args.curve.split(",")) if args.curve else (),
                           cache=DownstreamCache(None if args.no_cache else default_location()),
                           max_pixels=int(args.max_megapixels * 1e6) if args.max_megapixels > 0 else None)
    finally:
        if say is not None:
            say.close()
    if args.quiet:   # notes (files with the same pixels) matter for the result: said even when quiet
        for note in result.notes:
            print(f"g2r-downstream: note: {one_line(note)}", file=sys.stderr)
    print("Result: " + result.sentences[0])
    if result.isp is not None and result.sentences[0] != result.isp.sentence():
        print("Neural ISP: " + result.isp.sentence())
    if not args.dry_run:
        written = write_report(result, args.report)
        print(f"report: {written[1]} (and {', '.join(p.name for p in written if p != written[1])})")
    if result.problems:
        print(f"g2r-downstream: {len(result.problems)} file(s) left out (see above)", file=sys.stderr)
    return result.status


def main(argv=None) -> int:
    """Entry point of `g2r-downstream`; returns the exit status (0 ok, 1 some files left out, 2 error)."""
    return run_command("g2r-downstream", _run, argv, _parser(), check_arguments)


if __name__ == "__main__":
    sys.exit(main())
