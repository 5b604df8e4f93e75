"""Does `g2r-downstream DIR` (defaults) report the product a user gets from `g2r-fit-profile DIR`
then `g2r-downstream --profile`? Issue 43: the check's g2r_jax row must be made as
g2r-fit-profile makes the profile (lights and content model fitted), and the two ways must agree
within the seeds' spread.

For each camera: its NUS thumbnails written as small DNGs (`nus_dngs.write_camera_dngs`,
AsShotNeutral = the measured light), the CARLA frames as CG; the check run (1) with its
defaults, (2) with the profile `g2r-fit-profile` writes for the same folder. Prints the product
row ('fitted') and its control ('fitted_no_content') per estimator, with the seeds' means, the
wall time of each check, and each check's sentence.

    python benchmarks/check_product.py [--cameras Canon600D] [--estimators cnn] [--seeds 2] [--n 600]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def _row(report, row: str, estimator: str) -> str:
    summary = report.result.summary(row, estimator)
    seeds = " ".join(f"{m:.2f}" for m in summary["seed_means"])
    return f"{summary['mean']:.2f} (seeds {seeds})"


def run_camera(camera: str, estimators: tuple, seeds: int, n: int) -> None:
    import nus_dngs

    from g2r_jax.cli import fit_profile
    from g2r_jax.downstream import run_check

    cg = ROOT.parent / "shared" / "data" / "cg" / "carla"
    with tempfile.TemporaryDirectory() as work:
        folder = Path(work) / "dngs"
        nus_dngs.write_camera_dngs(camera, folder)
        profile = Path(work) / "profile.json"
        if fit_profile.main([str(folder), "-o", str(profile), "--quiet"]) != 0:
            raise SystemExit(f"g2r-fit-profile failed on {folder}")
        reports = {}
        for name, given in (("defaults", None), ("g2r-fit-profile, then --profile", profile)):
            start = time.perf_counter()
            reports[name] = run_check([folder], [cg], profile=None if given is None else str(given),
                                      estimators=estimators, seeds=seeds, n=n)
            reports[name].seconds = time.perf_counter() - start
    for name, report in reports.items():
        print(f"\n{camera}, {name} ({report.seconds:.0f} s):")
        for estimator in estimators:
            print(f"  {estimator}: product {_row(report, 'fitted', estimator)}; without content model "
                  f"{_row(report, 'fitted_no_content', estimator)}; UPI {_row(report, 'upi', estimator)}; "
                  f"real {_row(report, 'real', estimator)}")
        print("  " + report.sentences[0])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", default="Canon600D")
    parser.add_argument("--estimators", default="cnn")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--n", type=int, default=600)
    args = parser.parse_args(argv)
    for camera in args.cameras.split(","):
        run_camera(camera, tuple(args.estimators.split(",")), args.seeds, args.n)
    return 0


if __name__ == "__main__":
    sys.exit(main())
