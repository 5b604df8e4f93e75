"""Issue 29's pedestal case: a NikonD5200-like camera (black 600, white 16383), N files of HxW
dead-leaves scenes with every raw value raised by OFFSET of the range, no masked pixels and no
dark frames, audited against the profile without the pedestal. Prints the significant findings
(and black_level's line) with their held-out gains.

    python benchmarks/audit_pedestal_case.py OFFSET:SEED [OFFSET:SEED ...] [--files 24 --height 192 --width 288]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import g2r_jax
from g2r_jax.audit import diagnose, scenes, simulate, synthetic


def run(offset: float, seed: int, n: int, height: int, width: int) -> dict:
    camera = synthetic.levels_replaced(g2r_jax.load_profile("NikonD5200"), 600.0, 16383.0)
    truth = synthetic.inject(camera, "black_level", offset=offset)
    measured = simulate.simulate(truth, scenes.scene_set(n, 10_000 + seed, height, width), 50_000 + seed)
    started = time.perf_counter()
    report = diagnose(camera, measured, seed=seed)
    print(f"offset {offset:.4f} ({offset * (16383 - 600):.1f} DN), seed {seed}: {time.perf_counter() - started:.0f} s")
    for f in report["findings"]:
        if f["significant"] or f["cause"] == "black_level":
            gain = f.get("gain") or {}
            print(f"  {f['cause']:22s} significant={f['significant']!s:5s} score {f['score']:.1f} p {f['p']:.2g} "
                  f"kept={f.get('kept')} held-out {gain.get('before', np.nan):.3g} -> {gain.get('after', np.nan):.3g} "
                  f"{f.get('params', {}).get('black_pedestal_dn', [''])[0]}")
            print(f"      {f['evidence'][:400]}")
    return report


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+", help="OFFSET:SEED, e.g. 0.025:1")
    parser.add_argument("--files", type=int, default=24)
    parser.add_argument("--height", type=int, default=192)
    parser.add_argument("--width", type=int, default=288)
    args = parser.parse_args(argv)
    for case in args.cases:
        offset, seed = case.split(":")
        run(float(offset), int(seed), args.files, args.height, args.width)


if __name__ == "__main__":
    main()
