"""Speed of illuminant sampling per model, side by side in one run: `sample_neutrals` (jitted,
vmapped draws) for each model fitted to one NUS camera's measured lights, and the ratio to the
published Gaussian + hull. A draw is made once per converted image.

    python benchmarks/illuminant_sampling.py [--camera SonyA57] [--draws 100000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
NUS = ROOT.parent / "shared" / "data" / "estimation" / "nus"


def main(argv=None) -> int:
    import jax

    import g2r_jax
    from g2r_jax.downstream.base import real_sets
    from g2r_jax.illuminants import distributions
    from g2r_jax.profile.fitting import illuminant_model_for

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--camera", default="SonyA57")
    parser.add_argument("--draws", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    source = NUS / f"{args.camera}.npz"
    if not source.is_file():
        print(f"cannot run: needs {source}", file=sys.stderr)
        return 2
    lights = distributions.neutral_to_chromaticity(real_sets.load_nus(source).illuminants)
    colour = g2r_jax.load_profile(args.camera).colour
    timings = {}
    for kind in ("gaussian", "mixture", "kernel", "prior", "locus"):
        model = illuminant_model_for(lights, colour, kind)
        distributions.sample_neutrals(jax.random.PRNGKey(0), model, args.draws).block_until_ready()
        start = time.perf_counter()
        for repeat in range(args.repeats):
            distributions.sample_neutrals(jax.random.PRNGKey(repeat + 1), model, args.draws).block_until_ready()
        timings[kind] = (time.perf_counter() - start) / args.repeats / args.draws
        print(f"{kind:9s} {len(model.weights):4d} components  {timings[kind] * 1e6:6.2f} us per draw  "
              f"{timings[kind] / timings['gaussian']:.2f}x the Gaussian + hull")
    return 0


if __name__ == "__main__":
    sys.exit(main())
