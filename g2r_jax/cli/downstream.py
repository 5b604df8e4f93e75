"""g2r-downstream: does a network trained on g2r_jax RAW of your CG images work on your camera?

Trains illuminant estimators on synthetic RAW of the user's CG images (g2r_jax, and UPI as the
baseline), on the user's real DNGs (cross-validated), and on the controls that split the gap
(`g2r_jax.downstream.experiment`); tests each on the real DNGs, labelled by their AsShotNeutral.
Optionally the same for denoising on a burst (`g2r_jax.downstream.denoising`).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from g2r_jax.cli.common import (add_common_flags, command_parser, one_line, output_folder_problem, required_group,
                                run_command)

EXAMPLES = """  g2r-downstream --measured my_camera_dngs/ --cg renders/ --report downstream/
  g2r-downstream --measured my_camera_dngs/ --cg renders/ --profile my_camera.json --report downstream/ --seeds 3
  g2r-downstream --measured dngs/ --cg renders/ --burst burst_dngs/ --report downstream/
"""
DEFAULT_ESTIMATORS = "cnn,histogram"


def _parser() -> argparse.ArgumentParser:
    parser = command_parser(
        "g2r-downstream",
        "Train illuminant estimators on synthetic RAW made from your CG images (g2r_jax and UPI), on "
        "your real DNGs (cross-validated) and on controls; test them on your real DNGs (labelled by "
        "their AsShotNeutral, the camera's own white balance) and say how much of the gap to real "
        "training is the profile and how much the CG content.", EXAMPLES)
    required = required_group(parser)
    required.add_argument("--measured", required=True, nargs="+", metavar="DNG_DIR",
                          help="folders or files of real DNGs of one camera (at least 12 usable files)")
    required.add_argument("--cg", required=True, nargs="+", metavar="IMAGE_DIR",
                          help="folders or files of CG images (PNG, JPEG, TIFF sRGB; EXR linear), each at least "
                               "128 pixels on its shorter side")
    required.add_argument("--report", required=True, type=Path, metavar="DIR",
                          help="folder for report.json, report.md and the plot (created if missing)")
    parser.add_argument("--profile", metavar="NAME|FILE",
                        help="the camera's sensor profile (default: fitted from the measured DNGs as "
                             "g2r-fit-profile would; its lights are refitted per fold)")
    parser.add_argument("--burst", metavar="DNG_DIR",
                        help="also the denoising check: a folder of DNGs of one static scene (>= 3 frames)")
    parser.add_argument("--denoiser-steps", type=int, default=300, metavar="STEPS",
                        help="Adam steps per denoiser training of the burst check")
    parser.add_argument("--estimators", default=DEFAULT_ESTIMATORS,
                        help="comma-separated, of cnn, moments, histogram")
    parser.add_argument("--seeds", type=int, default=2, help="repetitions with new synthetic sets")
    parser.add_argument("--n", type=int, default=600, help="synthetic training images per set")
    parser.add_argument("--folds", type=int, default=3, help="cross-validation folds of the real files")
    add_common_flags(parser)
    return parser


def check_arguments(args) -> str | None:
    """The first problem found without reading any file (None when there is none)."""
    from g2r_jax.downstream.estimators import ESTIMATORS
    from g2r_jax.profile.shipped import UnknownProfile, profile_path

    for option, items in (("--measured", args.measured), ("--cg", args.cg)):
        for item in items:
            if not Path(item).exists():
                return f"{option} {item}: no such folder or file"
    if args.burst is not None and not Path(args.burst).is_dir():
        return f"--burst {args.burst}: no such folder"
    unknown = [e for e in args.estimators.split(",") if e not in ESTIMATORS]
    if unknown or not args.estimators:
        return f"--estimators {args.estimators}: expected some of {', '.join(ESTIMATORS)}"
    if args.seeds < 1 or args.n < 50 or args.folds < 2 or args.denoiser_steps < 1:
        return "--seeds must be >= 1, --n >= 50, --folds >= 2 and --denoiser-steps >= 1"
    if args.profile is not None:
        try:
            profile_path(args.profile)
        except UnknownProfile as error:
            return f"--profile {error}"
    return output_folder_problem("--report", args.report)


def read_cg_images(paths, say) -> tuple[list, list, list]:
    """Linear float32 CG images, their paths, and the (path, reason) of those that cannot be used."""
    import numpy as np

    from g2r_jax.colour.conversions import srgb_to_linear
    from g2r_jax.io.dng_info import DngError
    from g2r_jax.io.images import list_inputs, read_image

    images, used, skipped = [], [], []
    for path in list_inputs(paths):
        try:
            values, encoding = read_image(path)
        except DngError as error:
            skipped.append((str(path), error.problem))
            continue
        if min(values.shape[:2]) < 128:
            skipped.append((str(path), f"{values.shape[0]} x {values.shape[1]} is smaller than 128 pixels"))
            continue
        if encoding == "srgb":
            linear = np.asarray(srgb_to_linear(values), np.float32)
        else:   # scene-linear EXR: its 99.5th percentile is taken as the render's white
            linear = values / max(float(np.percentile(values.mean(-1), 99.5)), 1e-6)
        images.append(np.clip(linear, 0.0, 1.0).astype(np.float32))
        used.append(path)
    if say:
        say(f"{len(images)} CG image(s) read")
    return images, used, skipped


def _run(args) -> int:
    from g2r_jax.downstream import content, experiment, real_sets, report
    from g2r_jax.downstream.training_sets import cg_views, g2r_set, real_to_linear_srgb
    from g2r_jax.io.atomic import atomic_write_bytes
    from g2r_jax.io.dng_info import DngError

    say = None if args.quiet else (lambda message: print(f"g2r-downstream: {message}", file=sys.stderr))
    problems = []

    def bad(path, reason):
        problems.append((path, reason))
        print(f"g2r-downstream: error: {one_line(f'{path}: {reason}')}", file=sys.stderr)

    real, skipped = real_sets.load_dng_folder(args.measured)
    for path, reason in skipped:
        bad(path, reason)
    needed = max(12, 4 * args.folds)
    if len(real.images) < needed:
        raise DngError(" ".join(args.measured), f"{len(real.images)} usable DNG file(s); the check needs at least "
                                                f"{needed} (cross-validated real training)")
    if say:
        say(f"{len(real.images)} real DNG(s) of {real.name!r}, labelled by their {real_sets.DNG_LABEL}")
    cg, cg_paths, skipped = read_cg_images(args.cg, say)
    for path, reason in skipped:
        bad(path, reason)
    if not cg:
        raise DngError(" ".join(args.cg), "no usable CG image")
    burst = None
    if args.burst:   # read first: a burst that cannot be used is refused before minutes of training
        from g2r_jax.downstream.bursts import read_burst

        burst = read_burst(args.burst)
        for name, reason in burst.skipped:
            bad(name, reason)
    profile = _profile(args, real)
    rows = [r for r in experiment.DEFAULT_ROWS if args.profile is not None or r != "shipped"]
    estimators = tuple(args.estimators.split(","))
    result = experiment.illuminant_experiment(real, profile, cg, rows=rows, estimators=estimators,
                                              seeds=tuple(range(args.seeds)), n=args.n, folds=args.folds, progress=say)
    fitted = experiment.fitted_illuminants(profile, real.illuminants)
    synthetic = g2r_set(cg_views(cg, min(args.n, 300), 0), fitted, 0)
    round_trip = g2r_set(real_to_linear_srgb(real.images, real.illuminants, profile), profile, 0,
                         neutrals=real.illuminants)
    differences = content.compare(synthetic, (real.images, real.illuminants), round_trip)
    document = {"camera": real.name, "label": real.label, "files": list(real.files), **result.to_dict(),
                "decomposition": {e: report.decomposition(result, e) for e in estimators},
                "content": differences}
    sentences = [report.sentence(result, e, differences) for e in estimators]
    denoised = None
    if burst is not None:
        from g2r_jax.downstream import denoising

        denoised = denoising.denoising_benchmark(burst, profile, cg_paths, seeds=tuple(range(args.seeds)),
                                                 steps=args.denoiser_steps, progress=say)
        document["denoising"] = {"psnr": {f"{r}/{c}": v for (r, c), v in denoised.psnr.items()},
                                 "noisy_psnr": denoised.noisy_psnr, "noise": denoised.noise,
                                 "frames": list(denoised.frames), "iso": denoised.iso}
        sentences.append(denoising_sentence(denoised))
    document["problems"] = [{"path": p, "reason": r} for p, r in problems]
    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(folder / "report.json", (json.dumps(document, indent=1, default=float) + "\n").encode())
    markdown = [f"# Downstream check: {real.name}", "", f"Real files: {len(real.images)}; labels: {real.label}.", "",
                *sentences, "", report.table(result), "", "## What differs in the CG content", "",
                report.content_table(differences), ""]
    if denoised is not None:
        markdown += ["## Denoising on the burst", "", denoised.summary(), ""]
    atomic_write_bytes(folder / "report.md", "\n".join(markdown).encode())
    plotted = report.plot(result, folder / "errors.png")
    print("Result: " + sentences[0])
    print(f"report: {folder / 'report.md'} (and report.json{', errors.png' if plotted else ''})")
    if problems:
        print(f"g2r-downstream: {len(problems)} file(s) left out (see above)", file=sys.stderr)
    return 1 if problems else 0


def denoising_sentence(result) -> str:
    """One sentence: the denoiser trained with g2r_jax's noise on the CG content against UPI's and
    real pairs, on the burst's held-out frames."""
    import numpy as np

    mean = {key: float(np.mean(v)) for key, v in result.psnr.items() if len(v)}
    parts = [f"{label} {mean[key]:.2f} dB" for key, label in
             ((("shipped", "cg"), "g2r_jax noise on the CG images"), (("upi", "cg"), "UPI noise"),
              (("real", "scene"), "real pairs of the burst")) if key in mean]
    return (f"denoising the burst's held-out frames (noisy {result.noisy_psnr:.2f} dB): " + ", ".join(parts) + ".")


def _profile(args, real):
    """The given profile, or one fitted from the measured DNGs' tags (colour, levels, noise)."""
    from g2r_jax.io.dng_read import read_dng_info
    from g2r_jax.profile.fitting import fit_profile
    from g2r_jax.profile.schema import load_profile

    if args.profile is not None:
        return load_profile(args.profile)
    infos = [read_dng_info(path) for path in real.files]
    return fit_profile(infos, name=real.name or "measured", illuminant_model="prior")


def main(argv=None) -> int:
    """Entry point of `g2r-downstream`; returns the exit status (0 ok, 1 some files left out, 2 error)."""
    return run_command("g2r-downstream", _run, argv, _parser(), check_arguments)


if __name__ == "__main__":
    sys.exit(main())
