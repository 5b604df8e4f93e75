"""The audit on a synthetic burst with a known truth (issue 19, case 1): frames of a dim static
scene from a 10-bit sensor (black tag 64, true pedestal 0.16 DN, no NoiseProfile), optionally
with dark frames, against a profile holding the true noise and levels. Prints the summary and
every test's evidence.

    python benchmarks/audit_burst_case.py [HEIGHT WIDTH N_DARK]   (default 800 1200 0)
"""

from __future__ import annotations

import sys
import time

import g2r_jax
from g2r_jax.audit import diagnose, report
from g2r_jax.audit.synthetic_bursts import BurstTruth, burst, scene_signal, truth_profile

SPAN = 959


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    height, width, n_dark = (int(v) for v in (argv or ["800", "1200", "0"]))
    truth = BurstTruth(black_tag=64, pedestal=0.16, white=1023, shot=0.8 / 80 / SPAN, read=1.2 / SPAN**2, iso=800)
    files = burst(truth, scene_signal(3, height, width, low=0.008, high=0.12), 8, seed=1, n_dark=n_dark)
    started = time.perf_counter()
    result = diagnose(truth_profile(g2r_jax.load_profile("s20fe_night"), truth), files, seed=0)
    print(f"{time.perf_counter() - started:.0f} s")
    print(report.summary(result))
    for f in result["findings"]:
        print(f"  {f['cause']:24s} significant={f['significant']!s:5s} {f['evidence'][:220]}")


if __name__ == "__main__":
    main()
