"""The denoising downstream test (Graphics2RAW Table 1 protocol, `g2r_jax.downstream.denoising.burst_check`)
on a burst: prints the table (PSNR on WhiteLevel - BlackLevel, the reference's own noise taken
out), the noise models and the timings.

    python benchmarks/downstream_denoising.py [FOLDER] [--profile NAME_OR_JSON] [--seeds 0 1 2]
        [--steps N | --max-steps 3000] [--folds 2] [--cg 16] [--cg-folder ../shared/data/cg/carla]
        [--profile-noise-scale 1] [--dim] [--content-chroma S | --content-cast C | --content-scenes NUS_CAMERA] [--rows truth,upi]
        [--contents cg] [--workers N]

FOLDER: DNGs of one static scene from one camera (bad files are named and skipped). Without it,
a synthetic burst of 8 frames (192 x 256, a dim dead-leaves scene, no NoiseProfile tag) is made
from the profile's noise at --iso in a temporary folder, and its known noise is printed beside
the rows' models. `--dim`: instead, issue 34's kind of burst: 10-bit, black 60, white 1023,
ISO 100, the scene 13-60 DN above black and defocused, photon-transfer noise of a known truth
(shot 5.2e-4, read 2.4e-6 normalised), the profile given that truth. Without --steps the step
count is chosen on a validation split of the burst (`burst_check.choose_steps`).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

DEFAULT_CG = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "cg" / "carla"


def _nus_scenes_model(camera: str, profile):
    """The 'scenes' model of a NUS camera's thumbnails (balanced by their measured lights), carried
    to linear sRGB through `profile`'s matrices at D65 (CIE 15:2004 xy 0.3127, 0.3290), applied."""
    import jax.numpy as jnp
    import numpy as np

    from g2r_jax import content
    from g2r_jax.colour.dng_model import xy_to_camera_neutral
    from g2r_jax.downstream.base import real_sets

    real = real_sets.load_nus(DEFAULT_CG.parents[1] / "estimation" / "nus" / f"{camera}.npz")
    stats = content.statistics(content.white_balanced_camera_rgb(real.images, real.illuminants), source=camera)
    neutral = np.asarray(xy_to_camera_neutral(jnp.asarray([0.3127, 0.3290]), profile.colour), np.float64)
    to_camera = content.srgb_to_camera_matrices(neutral[None], profile.colour)[0]
    return content.with_default(content.fit_content_model(stats, family="scenes", to_camera=to_camera), True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", nargs="?", type=Path, help="folder of burst DNGs (default: a synthetic burst)")
    parser.add_argument("--profile", default="s20fe_night", help="shipped profile name or profile JSON")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=None, help="Adam steps per training (default: chosen)")
    parser.add_argument("--max-steps", type=int, default=3000, help="cap of the chosen step count")
    parser.add_argument("--dim", action="store_true", help="a dim, defocused 10-bit synthetic burst (issue 34)")
    parser.add_argument("--folds", type=int, default=2)
    parser.add_argument("--workers", type=int, default=None,
                        help="denoisers trained side by side (default: up to 4, at most the CPU count; 1: one at a time)")
    parser.add_argument("--cg", type=int, default=16, help="number of CG images (0: no CG content)")
    parser.add_argument("--cg-folder", type=Path, default=DEFAULT_CG)
    parser.add_argument("--iso", type=float, default=1600.0, help="ISO of the synthetic burst")
    parser.add_argument("--frames", type=int, default=8, help="frames of the synthetic burst")
    parser.add_argument("--profile-noise-scale", type=float, default=1.0,
                        help="multiply the profile's noise variance by this for the rows (not for the synthetic "
                             "burst): a deliberately wrong profile")
    parser.add_argument("--content-chroma", type=float, default=None,
                        help="give the rows' profile (not the synthetic burst) a content model of this chroma "
                             "scale, applied (issue 32: it must not hurt the CG rows)")
    parser.add_argument("--content-cast", type=float, default=None,
                        help="the same with a 'cast' content model keeping this share of each CG frame's cast")
    parser.add_argument("--content-scenes", default=None, metavar="NUS_CAMERA",
                        help="the same with the 'scenes' content model fitted to that NUS camera's scenes (their "
                             "thumbnails balanced by their lights; no burst camera has real scenes of its own here)")
    parser.add_argument("--rows", default=",".join(("upi", "shipped", "fitted", "truth", "real")),
                        help="comma-separated rows of the check")
    parser.add_argument("--contents", default="cg,scene", help="comma-separated contents: cg, scene")
    args = parser.parse_args(argv)

    import g2r_jax
    from g2r_jax.downstream.denoising import burst_check, bursts
    from g2r_jax.profile import schema
    from g2r_jax.pipeline import without_content

    started = time.perf_counter()
    # The rows measure the noise model: the CG frames go in without the profile's content model
    # unless --content-* gives one (the figures of the validation pages were measured so).
    profile = without_content(g2r_jax.load_profile(args.profile))
    cg = sorted(args.cg_folder.glob("*.png"))[:args.cg] if args.cg else []
    if args.cg and not cg:
        print(f"no CG images in {args.cg_folder}: CG content left out")
    contents = tuple(c for c in args.contents.split(",") if c != "cg" or cg)
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.folder
        if folder is None and args.dim:
            from g2r_jax.audit.synthetic_bursts import BurstTruth, truth_profile

            truth = BurstTruth(black_tag=60.0, white=1023.0, shot=5.2e-4, read=2.4e-6, iso=100.0)
            profile, folder = truth_profile(profile, truth), Path(scratch)
            bursts.write_synthetic_burst(folder, profile, n_frames=args.frames, height=192, width=256, iso=100.0,
                                         seed=0, low=13 / 963, high=60 / 963, fine=False, blur=3.0)
            print(f"synthetic dim burst: {args.frames} frames 256x192, 10-bit, black 60, white 1023, ISO 100, "
                  f"13-60 DN above black, defocused; known noise shot {truth.shot:.3g}, read {truth.read:.3g}")
        elif folder is None:
            folder = Path(scratch)
            _, truth = bursts.write_synthetic_burst(folder, profile, n_frames=args.frames, height=192, width=256,
                                                    iso=args.iso, seed=0)
            print(f"synthetic burst: {args.frames} frames 256x192 from {args.profile} at ISO {args.iso:g}; known "
                  f"noise shot {truth.shot:.3g}, read {truth.read:.3g} (normalised, before rounding)")
        burst = bursts.read_burst(folder)
        if args.profile_noise_scale != 1.0:
            noise = schema.replace(profile.noise, shot=profile.noise.shot * args.profile_noise_scale,
                                   read=profile.noise.read * args.profile_noise_scale)
            profile = schema.replace(profile, noise=noise)
            print(f"the rows' profile has {args.profile_noise_scale:g} times the noise variance of {args.profile}")
        if args.content_chroma is not None:
            from g2r_jax.content import content_model

            profile = schema.replace(profile, content=content_model(args.content_chroma, apply_by_default=True))
            print(f"the rows' profile applies a content model of chroma scale {args.content_chroma:g} to the CG images")
        if args.content_cast is not None:
            from g2r_jax.content import content_model

            profile = schema.replace(profile, content=content_model(cast_scale=args.content_cast, family="cast",
                                                                    apply_by_default=True))
            print(f"the rows' profile applies a 'cast' content model keeping {args.content_cast:g} of each CG "
                  "frame's cast")
        if args.content_scenes is not None:
            profile = schema.replace(profile, content=_nus_scenes_model(args.content_scenes, profile))
            print(f"the rows' profile applies the 'scenes' content model of {args.content_scenes}'s NUS scenes")
        read_s = time.perf_counter() - started
        result = burst_check.run_burst_check(burst, profile, cg, rows=tuple(args.rows.split(",")), contents=contents,
                                             seeds=args.seeds,
                                             steps=args.steps, max_steps=args.max_steps, folds=args.folds,
                                             cg_count=args.cg, workers=args.workers,
                                             progress=lambda line: print("  " + line, flush=True))
    total = time.perf_counter() - started
    print()
    print(result.summary())
    print()
    print("uncorrected PSNR (against the noisy reference as is):")
    for key, values in result.psnr_uncorrected.items():
        print(f"  {key[0]:8s} {key[1]:6s} " + " ".join(f"{v:.2f}" for v in values))
    print(f"\ntimes: reading {read_s:.1f} s, total {total:.0f} s wall; training per seed (s, all contents and "
          f"folds): " + ", ".join(f"{row} {sum(s) / len(s):.0f}" for row, s in result.seconds.items()))


if __name__ == "__main__":
    main()
