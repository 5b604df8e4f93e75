"""g2r-diagnose: measured DNGs vs a profile's simulation -> findings, held-out gains, REPORT.json
and an extended profile (issue 3). A thin front end over `g2r_jax.audit.diagnose`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from g2r_jax.io.dng_info import DngError
from g2r_jax.cli.common import add_debug_flag, error_message, one_line, run_command


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="g2r-diagnose",
        description="Compare measured DNGs of a camera with the simulation of its sensor profile: "
                    "name what the simulation gets wrong, fit the missing effects, measure the gain "
                    "on held-out files.")
    parser.add_argument("--profile", required=True, help="sensor profile (JSON path or shipped name)")
    parser.add_argument("--measured", help="folder of measured DNG files of the camera")
    parser.add_argument("--charts", help="measured colour charts of the camera (chart CSV, see g2r_jax.charts): "
                                         "tests and refits the colour matrices (cause colour_matrix)")
    parser.add_argument("--scenes", help="folder of scene images to simulate from (default: built-in "
                                         "dead-leaves scenes)")
    parser.add_argument("--report", required=True, help="REPORT.json to write")
    parser.add_argument("--extended-profile", help="write the profile with the kept extensions here")
    parser.add_argument("--html", help="folder for report.html and plots (default: next to the report)")
    parser.add_argument("--seed", type=int, default=0, help="seed of everything random (default 0)")
    parser.add_argument("--alpha", type=float, default=0.01, help="family-wise error rate (default 0.01)")
    parser.add_argument("--folds", type=int, default=3, help="cross-validation folds (default 3)")
    parser.add_argument("--quiet", action="store_true", help="no progress messages")
    add_debug_flag(parser)
    return parser


def _run(args) -> int:
    from g2r_jax.audit import diagnose, loading, report
    from g2r_jax.profile.schema import load_profile, save_profile

    if not 0 < args.alpha < 1:
        raise ValueError(f"--alpha {args.alpha}: must be between 0 and 1")
    if args.folds < 2:
        raise ValueError(f"--folds {args.folds}: need at least 2")
    report_path = Path(args.report)
    profile = load_profile(args.profile)
    if not args.measured and not args.charts:
        raise ValueError("give --measured DNG_DIR, --charts CHARTS.csv, or both")
    paths = loading.measured_paths(args.measured) if args.measured else None
    try:
        report_path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ValueError(f"{report_path}: cannot create its folder ({error.strerror})") from None
    say = None if args.quiet else (lambda message: print(f"g2r-diagnose: {message}", file=sys.stderr))
    failed = []

    def report_bad_file(line):
        failed.append(line)
        print(f"g2r-diagnose: error: {one_line(line)}", file=sys.stderr)

    try:
        result = diagnose(profile, paths, scenes=args.scenes, seed=args.seed, alpha=args.alpha,
                          folds=args.folds, progress=say, on_error=report_bad_file,
                          charts=args.charts)
    except DngError:
        raise
    except (ValueError, ArithmeticError) as error:   # a folder-wide problem: name the folder
        where = args.measured or args.charts
        what = f"these {len(paths)} file(s)" if paths else "these charts"
        raise DngError(where, f"cannot audit {what}: {error_message(error)}") from error
    if args.extended_profile:
        save_profile(result["profile"], args.extended_profile)
        result["extended_profile"] = str(args.extended_profile)
    report.write_json(result, report_path)
    report.write_html(result, Path(args.html) if args.html else report_path.parent / (report_path.stem + "_html"))
    print(report.summary(result))
    if failed:
        print(f"g2r-diagnose: {len(failed)} measured file(s) left out (see above)", file=sys.stderr)
    return 1 if failed else 0


def main(argv=None) -> int:
    """Entry point of `g2r-diagnose`; returns the exit status (0 ok, 2 error)."""
    return run_command("g2r-diagnose", _run, argv, _parser())


if __name__ == "__main__":
    sys.exit(main())
