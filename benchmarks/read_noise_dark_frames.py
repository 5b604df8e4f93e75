"""Issue 29: the read noise a fitted profile simulates in a black frame, against the dark frames of
the same (synthetic, S20 FE-like, 10-bit, black 60) sensor, per CFA site.

For each ISO: a burst of a dim dead-leaves scene and its dark frames written as DNGs without a
NoiseProfile (`tests/dark_frame_sensors.py`), profiles fitted by `fit_profile` from the burst
alone and from the burst with its dark frames; a black frame simulated from each; printed: the
ratio simulated / real dark variance per CFA site.

    python benchmarks/read_noise_dark_frames.py [--iso 100 400 1600 3200] [--seeds 1]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from dark_frame_sensors import dark_variance, s20fe, simulated_black_variance, write_folder  # noqa: E402

from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels  # noqa: E402
from g2r_jax.profile.fitting import fit_profile  # noqa: E402


def ratios(iso, seed, height, width, n_frames, n_dark, low, high):
    truth = s20fe(iso)
    with tempfile.TemporaryDirectory() as folder:
        burst, darks = write_folder(Path(folder), truth, n_frames=n_frames, n_dark=n_dark, height=height,
                                    width=width, seed=seed, low=low, high=high)
        real = dark_variance([read_dng_pixels(p) for p in darks])
        out = {}
        for label, paths in (("burst", burst), ("burst+dark", burst + darks)):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                profile = fit_profile([read_dng_info(p) for p in paths])
            out[label] = simulated_black_variance(profile, iso) / real
    return real, out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--iso", type=float, nargs="+", default=[100, 400, 1600, 3200])
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--size", type=int, nargs=2, default=[256, 384])
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--dark", type=int, default=6)
    parser.add_argument("--scene", type=float, nargs=2, default=[0.002, 0.3], help="signal range of the scene")
    args = parser.parse_args()
    start = time.time()
    for iso in args.iso:
        for seed in range(1, args.seeds + 1):
            real, found = ratios(iso, seed, *args.size, args.frames, args.dark, *args.scene)
            line = "  ".join(f"{k}: " + " ".join(f"{v:.2f}" for v in r) for k, r in found.items())
            print(f"ISO {iso:5g} seed {seed}: real dark variance {' '.join(f'{v:.3f}' for v in real)} DN^2;  "
                  f"simulated / real  {line}", flush=True)
    print(f"({time.time() - start:.0f} s)")


if __name__ == "__main__":
    main()
