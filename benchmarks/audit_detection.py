"""Detection and false-alarm rates of g2r-diagnose, and its run time (issue 3).

For every cause of the vocabulary and every seed: a measured set of FILES files (HxW) from the
demo camera with that effect injected at a random modest magnitude
(`g2r_jax.audit.synthetic.random_magnitude`), audited against the camera's clean profile. A
detection counts when the cause is named first *and* its extension has a positive held-out
gain. Clean sets (no effect) measure the false-alarm rate: any significant finding is one.

    /work/venv/bin/python benchmarks/audit_detection.py --seeds 5 [--workers 2] [--files 24]

Prints one line per run and a table; the first run includes JAX compilation (reported apart).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))


def one_run(job):
    cause, seed, n_files, height, width = job
    from g2r_jax.audit import diagnose, scenes, simulate, synthetic

    base = synthetic.demo_profile()
    rng = np.random.default_rng(1_000_003 * seed + (hash(cause) % 1000 if cause else 0))
    truth, magnitude = base, {}
    if cause:
        magnitude = synthetic.random_magnitude(cause, rng)
        truth = synthetic.inject(base, cause, height=height, width=width, **magnitude)
    measured = simulate.simulate(truth, scenes.scene_set(n_files, 10_000 + seed, height, width), 50_000 + seed)
    started = time.perf_counter()
    report = diagnose(base, measured, seed=seed)
    elapsed = time.perf_counter() - started
    found = [f for f in report["findings"] if f["significant"]]
    first = found[0] if found else None
    detected = bool(first and first["cause"] == cause and first.get("kept"))
    return {"cause": cause or "clean", "seed": seed, "magnitude": magnitude, "time": elapsed,
            "detected": detected, "named": [f["cause"] for f in found],
            "gain": first["gain"] if first else None}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--files", type=int, default=24)
    parser.add_argument("--height", type=int, default=200)
    parser.add_argument("--width", type=int, default=300)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--causes", default="all", help="comma-separated causes, or 'all'")
    parser.add_argument("--clean-seeds", type=int, default=None, help="clean sets (default: 2 x seeds)")
    args = parser.parse_args(argv)
    from g2r_jax.audit import CAUSES

    causes = list(CAUSES) if args.causes == "all" else args.causes.split(",")
    clean = args.clean_seeds if args.clean_seeds is not None else 2 * args.seeds
    jobs = [(c, s, args.files, args.height, args.width) for c in causes for s in range(args.seeds)]
    jobs += [(None, 1000 + s, args.files, args.height, args.width) for s in range(clean)]
    print(f"{len(jobs)} audits of {args.files} files of {args.height}x{args.width}, {args.workers} worker(s)")
    results = []
    if args.workers > 1:
        with ProcessPoolExecutor(args.workers) as pool:
            for r in pool.map(one_run, jobs):
                results.append(r)
                print(f"  {r['cause']:24s} seed {r['seed']:4d}  detected={r['detected']!s:5s} named={r['named']} "
                      f"{r['time']:.1f}s {r['magnitude']}", flush=True)
    else:
        for job in jobs:
            r = one_run(job)
            results.append(r)
            print(f"  {r['cause']:24s} seed {r['seed']:4d}  detected={r['detected']!s:5s} named={r['named']} "
                  f"{r['time']:.1f}s {r['magnitude']}", flush=True)
    print("\ncause                     detection rate   (named first, held-out gain > 0)")
    for cause in causes:
        rows = [r for r in results if r["cause"] == cause]
        print(f"{cause:24s}  {sum(r['detected'] for r in rows)}/{len(rows)}")
    clean_rows = [r for r in results if r["cause"] == "clean"]
    alarms = sum(bool(r["named"]) for r in clean_rows)
    print(f"{'clean (false alarms)':24s}  {alarms}/{len(clean_rows)}")
    times = np.array([r["time"] for r in results])
    print(f"\ntime per audit: median {np.median(times):.1f} s, max {times.max():.1f} s "
          f"(first run of each worker includes JAX compilation: {times[0]:.1f} s)")


if __name__ == "__main__":
    main()
