"""Run time of g2r-diagnose on real-size DNGs (issue 9): one 12-MP DNG, and N copies of it.

    python benchmarks/audit_speed.py [--dng ../shared/data/dng/gopro_hero6_GOPR0024.dng]
        [--profile gopro_hero6] [--copies 24] [--runs 2]

Prints the wall time of each audit; the first run of the process includes JAX compilation of the
simulation (the CLI keeps compilations in a persistent cache, so later runs do not pay it). The
copies are the same file read N times (statistics cost per file, simulation cost per audit).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dng", default=str(Path(__file__).parents[1] / ".." / "shared" / "data" / "dng"
                                             / "gopro_hero6_GOPR0024.dng"))
    parser.add_argument("--profile", default="gopro_hero6")
    parser.add_argument("--copies", type=int, default=24)
    parser.add_argument("--runs", type=int, default=2, help="audits of the single file (the first compiles)")
    args = parser.parse_args(argv)
    import g2r_jax
    from g2r_jax.audit import diagnose

    profile = g2r_jax.load_profile(args.profile)
    for run in range(args.runs):
        started = time.perf_counter()
        result = diagnose(profile, [args.dng], seed=0)
        first = result["findings"][0]
        print(f"1 file, run {run + 1}: {time.perf_counter() - started:.1f} s "
              f"(statistics and first simulation {result['timing']['statistics_s']:.1f} s); first finding "
              f"{first['cause']} significant={first['significant']}", flush=True)
    if args.copies > 1:
        started = time.perf_counter()
        result = diagnose(profile, [args.dng] * args.copies, seed=0)
        print(f"{args.copies} files: {time.perf_counter() - started:.1f} s; first finding "
              f"{result['findings'][0]['cause']}", flush=True)


if __name__ == "__main__":
    main()
