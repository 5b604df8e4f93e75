"""What sets the CG frames apart from real scenes, as the estimator sees them: the content
statistics of `g2r_jax.downstream.illuminant.content` for the CARLA views made RAW with each NUS camera's
fitted profile, against the camera's real thumbnails and against those thumbnails made RAW again
by g2r_jax (what the simulation alone moves a statistic).

    python benchmarks/downstream_content.py [--views 500] [--seed 0] [--content-model none|cast|scenes]
        [--statistics brightness,chroma_spread,...]

`--content-model`: the CG views first go through that family of `g2r_jax.content`, fitted (no
labels) to all the camera's real thumbnails balanced by their lights, as `g2r-fit-profile` would
from its DNGs (default none: the views as they are).

Prints one Markdown table: per camera and statistic, the CG median vs the real median, and the
distances (in the real set's robust standard deviations) of the CG set and of the round trip.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from downstream_nus import CAMERAS, CARLA, NUS, camera_profile  # noqa: E402


def main(argv=None) -> int:
    from PIL import Image

    from g2r_jax.downstream.base import product, real_sets, training_sets
    from g2r_jax.downstream.illuminant import content

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--views", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--content-model", default="none", choices=("none", "cast", "scenes"))
    parser.add_argument("--statistics", default=",".join(content.STATISTICS))
    args = parser.parse_args(argv)
    if not NUS.is_dir() or not CARLA.is_dir():
        print(f"cannot run: needs {NUS} and {CARLA}", file=sys.stderr)
        return 2
    frames = [np.asarray(Image.open(f).convert("RGB")) for f in sorted(CARLA.glob("*.png"))]
    views = training_sets.cg_views(training_sets.linear_images(frames), args.views, args.seed)
    names = args.statistics.split(",")
    print("| camera | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for camera in CAMERAS:
        real = real_sets.load_nus(NUS / f"{camera}.npz")
        profile = camera_profile(camera)
        adapted = views
        if args.content_model != "none":
            model = product.candidate_model(args.content_model, real.images, real.illuminants, views, profile)
            adapted = product.adapted_views(model, views, args.seed)
        synthetic = training_sets.g2r_set(adapted, product.fitted_illuminants(profile, real.illuminants), args.seed)
        round_trip = training_sets.g2r_set(training_sets.real_to_linear_srgb(real.images, real.illuminants, profile),
                                           profile, args.seed, neutrals=real.illuminants)
        rows = {r["statistic"]: r for r in content.compare(synthetic, (real.images, real.illuminants), round_trip)}
        print(f"| {camera} | " + " | ".join(
            f"{rows[s]['synthetic']:.3g} vs {rows[s]['real']:.3g} ({rows[s]['distance']:+.1f}; round trip "
            f"{rows[s]['control_distance']:+.1f})" for s in names) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
