"""Wall time of the downstream colour check as a user runs it (issue 44): `run_check` on a NUS
camera's thumbnails written as small DNGs (`nus_dngs.write_camera_dngs`) with the 343 CARLA
frames, the default rows plus the content rows, both default estimators, 2 seeds; the rows of
a fold trained one at a time (`workers=1`, as before) and side by side (`workers=None`), in one
process after a warm-up run (so compilation is not counted), with each run's product row.

    python benchmarks/check_speed.py [--camera Canon600D] [--repeats 1]
    python benchmarks/check_speed.py --second-run [--camera Canon600D]

`--second-run` (issue 52): the check with the store of finished trainings (`downstream.base.cache`, an
empty folder), run twice on the same inputs: the first run fills it, the second reuses it; both
wall times and product rows printed side by side. `--tasks isp` (with `--second-run`): the neural
ISP's part of the check (`g2r-downstream --tasks isp`) instead of the colour check, its product
row's ΔE2000 printed.

    python benchmarks/check_speed.py --second-run --tasks isp [--camera Canon600D]
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


def main(argv=None) -> int:
    import nus_dngs

    from g2r_jax.downstream import default_rows, run_check
    from g2r_jax.runtime import compile_cache

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--camera", default="Canon600D")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--second-run", action="store_true", help="first and second run with the cache")
    parser.add_argument("--tasks", default="colour", choices=("colour", "isp"),
                        help="with --second-run: the task timed (default colour)")
    args = parser.parse_args(argv)
    compile_cache.enable()
    cg = ROOT.parent / "shared" / "data" / "cg" / "carla"
    with tempfile.TemporaryDirectory() as work:
        paths = nus_dngs.write_camera_dngs(args.camera, Path(work) / "dngs")
        print(f"{len(paths)} DNGs of {args.camera}, {len(list(cg.glob('*.png')))} CG frames")

        def check(workers):
            start = time.perf_counter()
            report = run_check([Path(work) / "dngs"], [cg], rows=default_rows(False, content_rows=True), workers=workers)
            summary = report.result.summary("fitted", "cnn")
            return time.perf_counter() - start, summary["mean"], summary["seed_means"]

        if args.second_run:
            return _second_run(Path(work) / "dngs", cg, Path(work) / "cache", args.tasks)
        check(None)   # warm-up: compilation, caches on disk
        for _ in range(args.repeats):
            for workers in (1, None):
                seconds, mean, seeds = check(workers)
                print(f"workers={workers}: {seconds:.1f} s; product row (cnn) {mean:.2f} deg, seeds "
                      + " ".join(f"{s:.2f}" for s in seeds))
    return 0


def _second_run(dngs: Path, cg: Path, store: Path, task: str = "colour") -> int:
    """The check (its colour or ISP task) twice with one store: wall time and product row of each run."""
    from g2r_jax.downstream import default_rows, run_check
    from g2r_jax.downstream.base.cache import DownstreamCache

    for label in ("first run (empty store)", "second run (same inputs)"):
        cache = DownstreamCache(store)
        start = time.perf_counter()
        options = {"tasks": ("isp",)} if task == "isp" else {"rows": default_rows(False, content_rows=True)}
        report = run_check([dngs], [cg], cache=cache, **options)
        seconds = time.perf_counter() - start
        product = (f"ΔE2000 {report.isp.summary('fitted', 'delta_e')['mean']:.2f}" if task == "isp"
                   else f"{report.result.summary('fitted', 'cnn')['mean']:.2f} deg")
        print(f"{label}: {seconds:.1f} s; {cache.summary()}; product row ({task}) {product}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
