"""Issue 34's single denoised file: one HxW file of a shipped camera (dead-leaves scene),
denoised in-camera above a knee (`synthetic.denoised_above`: each CFA plane pulled towards its
3 x 3 same-colour mean by STRENGTH where that mean is above KNEE of the range), no dark frames,
audited against the clean profile. Prints the significant findings, their held-out gains and
the pedestal weighing (`audit.scene_pedestal`).

    python benchmarks/audit_denoised_case.py PROFILE:KNEE:STRENGTH:SEED [...] [--height 1000 --width 1500]

e.g. the issue's case: `NikonD5200:0.13:0.84:0`.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))


def run(profile_name: str, knee: float, strength: float, seed: int, height: int, width: int) -> dict:
    import g2r_jax
    from g2r_jax.audit import diagnose, scenes, simulate, synthetic

    camera = g2r_jax.load_profile(profile_name)
    (mosaic, info), = simulate.simulate(camera, scenes.scene_set(1, 10_000 + seed, height, width), 50_000 + seed)
    denoised = synthetic.denoised_above(mosaic, info, knee, strength)
    started = time.perf_counter()
    report = diagnose(camera, [(denoised, info)], seed=seed)
    print(f"{profile_name} knee {knee:.3f} strength {strength:.2f} seed {seed} {height}x{width}: "
          f"{time.perf_counter() - started:.0f} s", flush=True)
    for f in report["findings"]:
        if f["significant"]:
            gain = f.get("gain") or {}
            print(f"  {f['cause']:22s} source={f.get('source')} score {f['score']:.1f} p {f['p']:.2g} kept={f.get('kept')} "
                  f"held-out {gain.get('before', float('nan')):.3g} -> {gain.get('after', float('nan')):.3g}", flush=True)
            print(f"      {f['evidence'][:600]}", flush=True)
    return report


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+", help="PROFILE:KNEE:STRENGTH:SEED, e.g. NikonD5200:0.13:0.84:0")
    parser.add_argument("--height", type=int, default=1000)
    parser.add_argument("--width", type=int, default=1500)
    args = parser.parse_args(argv)
    for case in args.cases:
        name, knee, strength, seed = case.split(":")
        run(name, float(knee), float(strength), int(seed), args.height, args.width)


if __name__ == "__main__":
    main()
