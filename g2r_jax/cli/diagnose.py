"""g2r-diagnose: measured DNGs vs a profile's simulation -> findings, held-out gains, REPORT.json
and an extended profile (issue 3). A thin front end over `g2r_jax.audit.diagnose`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from g2r_jax.cli.common import (
    add_common_flags, command_parser, error_message, one_line, output_file_problem, output_folder_problem,
    required_group, run_command)


EXAMPLES = """  g2r-diagnose --profile my_camera.json --measured my_camera_dngs/ --report audit/REPORT.json
  g2r-diagnose --profile gopro_hero6 --measured GOPR0024.dng --report gopro/REPORT.json
  g2r-diagnose --profile gopro_hero6 --measured dngs/ --report r.json --extended-profile gopro_extended.json
"""


def _parser() -> argparse.ArgumentParser:
    parser = command_parser(
        "g2r-diagnose",
        "Compare measured DNGs of a camera with the simulation of its sensor profile: "
        "name what the simulation gets wrong, fit the missing effects, measure the gain "
        "on held-out files.", EXAMPLES)
    required = required_group(parser)
    required.add_argument("--profile", required=True, metavar="NAME|FILE",
                          help="sensor profile: a shipped name or the path of a profile JSON file")
    required.add_argument("--report", required=True, type=Path, metavar="REPORT_JSON",
                          help="REPORT.json to write (its folder is created if missing)")
    parser.add_argument("--measured", metavar="DNG_DIR",
                        help="folder of measured DNG files of the camera, or one DNG file (this, --charts, "
                             "or both)")
    parser.add_argument("--charts", metavar="CSV",
                        help="measured colour charts of the camera (chart CSV, see g2r_jax.colour.charts): "
                             "tests and refits the colour matrices (cause colour_matrix)")
    parser.add_argument("--scenes", help="folder of scene images to simulate from (default: built-in "
                                         "dead-leaves scenes)")
    parser.add_argument("--extended-profile", type=Path, metavar="PROFILE_JSON",
                        help="write the profile with the kept extensions here (default: REPORT_profile.json "
                             "next to the report, when an extension was kept)")
    parser.add_argument("--html", type=Path, metavar="DIR",
                        help="folder for report.html and plots (default: next to the report, REPORT_html/)")
    parser.add_argument("--seed", type=int, default=0, help="seed of everything random")
    parser.add_argument("--alpha", type=float, default=0.01, help="family-wise error rate")
    parser.add_argument("--folds", type=int, default=3, help="cross-validation folds")
    add_common_flags(parser)
    return parser


def check_arguments(args) -> str | None:
    """The first problem of the arguments found without reading any file (None when there is none)."""
    from g2r_jax.profile.shipped import UnknownProfile, profile_path

    if not 0 < args.alpha < 1:
        return f"--alpha {args.alpha}: must be between 0 and 1"
    if args.folds < 2:
        return f"--folds {args.folds}: need at least 2"
    if not args.measured and not args.charts:
        return "give --measured DNG_DIR, --charts CHARTS.csv, or both"
    if args.charts is not None and not Path(args.charts).is_file():
        return f"--charts {args.charts}: no such file"
    if args.measured is not None and not Path(args.measured).exists():
        return f"--measured {args.measured}: no such folder or file"
    if args.scenes is not None and not Path(args.scenes).exists():
        return f"--scenes {args.scenes}: no such folder"
    try:
        profile_path(args.profile)
    except UnknownProfile as error:
        return f"--profile {error}"
    return (output_file_problem("--report", args.report, create_folder=True)
            or (args.extended_profile and output_file_problem("--extended-profile", args.extended_profile,
                                                              create_folder=True))
            or (args.html and output_folder_problem("--html", args.html)) or None)


def _run(args) -> int:
    from g2r_jax.audit import diagnose, loading, report
    from g2r_jax.profile.schema import load_profile, save_profile
    from g2r_jax.colour.charts import ChartError
    from g2r_jax.io.dng_info import DngError

    report_path = Path(args.report)   # --alpha, --folds, inputs and output paths: checked while parsing
    profile = load_profile(args.profile)
    paths = loading.measured_paths(args.measured) if args.measured else None
    for folder in {report_path.parent} | ({args.extended_profile.parent} if args.extended_profile else set()):
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise ValueError(f"{folder}: cannot create this folder ({error.strerror})") from None
    say = None if args.quiet else (lambda message: print(f"g2r-diagnose: {message}", file=sys.stderr))
    failed = []

    def report_bad_file(line):
        failed.append(line)
        print(f"g2r-diagnose: error: {one_line(line)}", file=sys.stderr)

    try:
        result = diagnose(profile, paths, scenes=args.scenes, seed=args.seed, alpha=args.alpha,
                          folds=args.folds, progress=say, on_error=report_bad_file,
                          charts=args.charts)
    except (DngError, ChartError):   # already one line naming the file (and its row)
        raise
    except (ValueError, ArithmeticError) as error:   # a folder-wide problem: name the folder
        where = args.measured or args.charts
        what = f"these {len(paths)} file(s)" if paths else "these charts"
        raise DngError(where, f"cannot audit {what}: {error_message(error)}") from error
    kept = any(f.get("kept") for f in result["findings"])
    extended_path = Path(args.extended_profile) if args.extended_profile else \
        report_path.parent / f"{report_path.stem}_profile.json"
    if args.extended_profile or kept:
        save_profile(result["profile"], extended_path)
        result["extended_profile"] = str(extended_path)
    result["report_path"] = str(report_path)
    report.write_json(result, report_path)
    page = report.write_html(result, Path(args.html) if args.html else report_path.parent / (report_path.stem + "_html"))
    print(report.summary(result))
    print(f"report: {report_path}")
    print(f"HTML report: {page}")
    if result.get("extended_profile"):
        print(f"extended profile (the profile with every kept extension): {result['extended_profile']}")
    if failed:
        print(f"g2r-diagnose: {len(failed)} measured file(s) left out (see above)", file=sys.stderr)
    return 1 if failed else 0


def main(argv=None) -> int:
    """Entry point of `g2r-diagnose`; returns the exit status (0 ok, 2 error)."""
    return run_command("g2r-diagnose", _run, argv, _parser(), check_arguments)


if __name__ == "__main__":
    sys.exit(main())
