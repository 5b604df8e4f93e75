"""Run time of g2r-diagnose on real-size DNGs (issue 9: one 12-MP DNG in under 20 s, 24 in under
60 s on 2 cores), measured as a user runs it: the command in a fresh process, report and HTML
written.

    python benchmarks/audit_speed.py [--dng ../shared/data/dng/gopro_hero6_GOPR0024.dng]
        [--profile gopro_hero6] [--copies 24]

Runs, each a new `python -m g2r_jax.cli.diagnose` process (interpreter start and imports
included), with its own empty compilation cache in a temporary folder:
1. one file, cold cache (every XLA program compiled, as on a user's first run);
2. one file, warm cache (every later run; the command keeps compilations on disk);
3. one file, warm cache, with a second job on the machine: a process spinning on one core (as a
   training job's data loader or a second command would), started before and stopped after;
4. COPIES files, warm cache: the same DNG linked COPIES times into one folder (only one real
   12-MP frame is at hand; statistics cost per file, so copies time the per-file work honestly,
   though identical files make every cross-validation fold fit the same parameters).
Prints the one-file and COPIES-file times side by side with the first finding of each.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def audit(folder: Path, profile: str, cache: Path, out: Path) -> tuple[float, dict]:
    """Wall time of one g2r-diagnose process on `folder`, and its report."""
    env = dict(os.environ, G2R_JAX_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    env.pop("G2R_JAX_NO_COMPILE_CACHE", None)
    report = out / "report.json"
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "g2r_jax.cli.diagnose", "--profile", profile, "--measured",
                           str(folder), "--report", str(report), "--quiet"], env=env, capture_output=True, text=True)
    elapsed = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"g2r-diagnose failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return elapsed, json.loads(report.read_text())


def first(report: dict) -> str:
    f = report["findings"][0]
    return f"{f['cause']} (significant={f['significant']})"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dng", default=str(ROOT / ".." / "shared" / "data" / "dng" / "gopro_hero6_GOPR0024.dng"))
    parser.add_argument("--profile", default="gopro_hero6")
    parser.add_argument("--copies", type=int, default=24)
    args = parser.parse_args(argv)
    dng = Path(args.dng).resolve()
    if not dng.exists():
        raise SystemExit(f"{dng}: not found (the real GoPro frame lives in ../shared/data/dng)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        one, many, cache = tmp / "one", tmp / "many", tmp / "cache"
        one.mkdir()
        many.mkdir()
        (one / dng.name).symlink_to(dng)
        for i in range(args.copies):
            (many / f"{dng.stem}_{i:02d}{dng.suffix}").symlink_to(dng)
        rows = []
        cold, report = audit(one, args.profile, cache, one)
        rows.append(("1 file, cold compilation cache", cold, first(report)))
        print(f"{rows[-1][0]}: {cold:.1f} s, first finding {rows[-1][2]}", flush=True)
        warm, report = audit(one, args.profile, cache, one)
        rows.append(("1 file, warm cache", warm, first(report)))
        print(f"{rows[-1][0]}: {warm:.1f} s, first finding {rows[-1][2]}", flush=True)
        spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        try:
            busy, report = audit(one, args.profile, cache, one)
        finally:
            spinner.kill()
            spinner.wait()
        rows.append(("1 file, warm cache, a second job running", busy, first(report)))
        print(f"{rows[-1][0]}: {busy:.1f} s, first finding {rows[-1][2]}", flush=True)
        if args.copies > 1:
            elapsed, report = audit(many, args.profile, cache, many)
            rows.append((f"{args.copies} files (copies), warm cache", elapsed, first(report)))
            print(f"{rows[-1][0]}: {elapsed:.1f} s, first finding {rows[-1][2]}", flush=True)
    print(f"\n{'run':40s} {'wall s':>7s}  first finding   ({os.cpu_count()} cores, {dng.name}, {args.profile})")
    for name, seconds, finding in rows:
        print(f"{name:40s} {seconds:7.1f}  {finding}")


if __name__ == "__main__":
    main()
