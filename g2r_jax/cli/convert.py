"""g2r-convert: CG images (PNG/JPEG/TIFF sRGB, linear EXR) -> DNGs of the profiled camera."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from g2r_jax.cli.common import (
    add_common_flags, command_parser, output_folder_problem, required_group, run_command)
from g2r_jax.cli.common import error_message, one_line, shown

DEFAULT_EXAMPLE_PROFILE = "Canon600D"
USAGE = """g2r-convert INPUT [INPUT ...] --profile NAME|FILE -o OUT_DIR [options]
       g2r-convert --example -o OUT_DIR [--profile NAME|FILE] [options]
       g2r-convert --list-profiles"""
EXAMPLES = """  g2r-convert renders/ --profile gopro_hero6 -o dngs/
  g2r-convert sceneA/ sceneB/ --profile my_camera.json -o dngs/ --iso 800   # dngs/sceneA/..., dngs/sceneB/...
  g2r-convert --example -o example_dng/
  g2r-convert renders/ --profile my_camera.json -o dngs/ --pairs   # + x.clean.dng, x.scene.png per x.dng
"""
# Measured (docs/pages/guide/renderers.md): Adobe's SDK interpolates the matrices by the white's
# temperature as the DNG specification says; LibRaw, RawTherapee 5.9 and darktable 4.2.1 use one.
RENDERER_NOTE = ("to view: Adobe's renderers (Lightroom, Camera Raw, DNG SDK) read the colour tags as written; "
                 "LibRaw (rawpy), RawTherapee and darktable use one matrix, so warm or night scenes show casts "
                 "not in the data")


class _ListProfiles(argparse.Action):
    """--list-profiles: print each shipped profile and what it is, then exit (no other option needed)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        from g2r_jax.profile.provenance import describe_shipped_profiles

        print(describe_shipped_profiles())   # camera, ISO range, sources of colour, noise, illuminants
        parser.exit(0)


def build_parser() -> argparse.ArgumentParser:
    parser = command_parser("g2r-convert", __doc__, EXAMPLES, usage=USAGE)
    parser.add_argument("inputs", nargs="*", type=Path, metavar="INPUT",
                        help="image files or folders; files from several folders keep their folders under OUT_DIR")
    required = required_group(parser)
    required.add_argument("--profile", metavar="NAME|FILE",
                          help="a shipped profile name (see --list-profiles) or the path of a profile JSON file; "
                               f"with --example it defaults to {DEFAULT_EXAMPLE_PROFILE}")
    required.add_argument("-o", "--output", type=Path, required=True, metavar="OUT_DIR",
                          help="output folder (created if missing)")
    parser.add_argument("--seed", type=int, default=0,
                        help="random seed of illuminants, exposure and noise; each file's key derives "
                             "from the seed and its name, so the same seed gives the same bytes")
    parser.add_argument("--iso", type=float, help="fixed ISO instead of one drawn per image")
    parser.add_argument("--no-noise", action="store_true", help="do not add sensor noise")
    parser.add_argument("--no-effects", action="store_true", help="do not add the profile's sensor effects")
    content = parser.add_mutually_exclusive_group()
    content.add_argument("--content-model", action="store_true",
                         help="apply the profile's content model (shipped profiles and g2r-fit-profile's carry "
                              "one, on by default) even where the profile leaves it off; a profile without one "
                              "gets the 'cast' model of the prior of real scenes")
    content.add_argument("--no-content-model", action="store_true",
                         help="do not apply the profile's content model")
    content.add_argument("--content-cast-only", action="store_true",
                         help="apply only the content model's median cast (the 'cast' model), not each scene's "
                              "cast and brightness: the neural ISP trained better so (see docs "
                              "validation/content_model)")
    parser.add_argument("--pairs", action="store_true",
                        help="also write what each task trains on beside each x.dng: x.clean.dng (no noise: the "
                             "denoising target), x.scene.png (16-bit sRGB: the frame as the camera saw it, after "
                             "the content model; the ISP's target; x.scene.exr too for linear inputs); the "
                             "manifest gives each file's light in camera RGB (illuminant_rgb) and its pair's names")
    parser.add_argument("--developed", action="store_true",
                        help="with --pairs (implied): also x.developed.png, the clean DNG developed by the "
                             "check's reference developer (LibRaw at the as-shot white balance)")
    parser.add_argument("--illuminants", type=Path, metavar="CSV",
                        help="CSV with columns r_over_g,g,b_over_g; row i for the i-th input in sorted order")
    parser.add_argument("--transfer", choices=["auto", "srgb", "gamma2.2", "linear"], default="auto",
                        help="decoding of input values (auto: sRGB for PNG/JPEG/TIFF, linear for EXR)")
    parser.add_argument("--recipe", choices=["dng", "published"], default="dng",
                        help="colour model: exact DNG inverse or the published approximation")
    parser.add_argument("--colour", choices=["matrix", "spectral", "spectral-jakob2019"], default="matrix",
                        help="colour model: DNG matrices or the spectral sensor model (sensitivities from "
                             "the profile, else estimated from its matrices)")
    parser.add_argument("--batch-size", type=int, default=4,
                        help="images of one size converted together in one compiled call; "
                             "larger uses more memory, the output bytes do not change")
    parser.add_argument("--workers", type=int, default=2, help="decode/encode threads")
    parser.add_argument("--compression", choices=["none", "ljpeg"], default="none",
                        help="DNG pixel data: uncompressed, or lossless JPEG tiles (DNG Compression 7, read by "
                             "LibRaw and the Adobe DNG SDK): 0.4-0.65 of the size for about 0.3 s more CPU "
                             "a 12-MP frame")
    parser.add_argument("--crop-odd", action="store_true", help="drop the last row/column of odd-sized images")
    parser.add_argument("--max-megapixels", type=float, default=100.0, metavar="MPX",
                        help="largest image accepted, read from its header before decoding; larger ones are "
                             "refused by name (0: no limit)")
    parser.add_argument("--max-batch-megapixels", type=float, default=200.0, metavar="MPX",
                        help="pixels of one compiled call: fewer images go together above it (0: no limit)")
    parser.add_argument("--lens-shading", action="store_true",
                        help="apply the inverse of the camera's lens shading (profile OpcodeList2) and write the opcode")
    parser.add_argument("--engine", choices=["local", "ray"], default="local",
                        help="local: this machine; ray: spread the files over a Ray cluster "
                             "(pip install g2r_jax[ray]); same bytes either way")
    parser.add_argument("--example", action="store_true", help="convert the built-in example scene")
    parser.add_argument("--list-profiles", action=_ListProfiles, help="list the shipped profiles and what each is, and exit")
    add_common_flags(parser)
    return parser


def check_arguments(args) -> str | None:
    """The first problem of the arguments found without reading any input (None when there is none)."""
    from g2r_jax.profile.shipped import UnknownProfile, profile_path

    if not args.example and not args.inputs:
        return "no INPUT given (image files or folders), or use --example"
    if not args.example and not args.profile:
        return "the following arguments are required: --profile (a shipped name, see --list-profiles, or a JSON file)"
    for option, value in (("--batch-size", args.batch_size), ("--workers", args.workers)):
        if value < 1:
            return f"{option} {value}: must be at least 1"
    if args.iso is not None and not args.iso > 0:
        return f"--iso {args.iso}: must be a positive number"
    if args.illuminants is not None and not args.illuminants.is_file():
        return f"--illuminants {args.illuminants}: no such file"
    try:
        profile_path(args.profile or DEFAULT_EXAMPLE_PROFILE)
    except UnknownProfile as error:
        return f"--profile {error}"
    return output_folder_problem("-o", args.output)


def read_illuminant_csv(path: Path):
    """Rows (r/g, g, b/g) -> (N, 3) neutrals normalised to G = 1; errors name the file and row."""
    import csv

    import numpy as np

    from g2r_jax.io.dng_info import DngError

    try:
        with open(path, newline="") as handle:
            rows = list(csv.DictReader(handle))
    except (OSError, UnicodeDecodeError) as error:
        raise DngError(path, f"cannot read illuminant CSV ({error})") from None
    needed = {"r_over_g", "g", "b_over_g"}
    if not rows or not needed <= set(rows[0]):
        raise DngError(path, "expected a header with columns r_over_g,g,b_over_g and at least one row")
    neutrals = []
    for number, row in enumerate(rows, start=2):
        try:
            values = np.array([float(row["r_over_g"]), float(row["g"]), float(row["b_over_g"])])
        except (TypeError, ValueError):
            raise DngError(path, f"line {number}: not three numbers") from None
        if not np.all(np.isfinite(values)) or np.any(values <= 0):
            raise DngError(path, f"line {number}: values must be positive and finite")
        neutrals.append(values / values[1])
    return np.stack(neutrals)


def _content_choice(profile, args, say):
    """The profile with its content model kept, forced on or dropped as the flags say."""
    from g2r_jax.content import as_cast, describe, prior_scenes_model, with_default
    from g2r_jax.profile.schema import replace

    model = profile.content
    if args.content_model and model is None:
        model = prior_scenes_model(profile.colour)
        say(f"profile {shown(profile.info.name)} has no content model: using the prior of real scenes' "
            "(g2r-fit-profile fits one to the camera's DNGs)")
    if model is None:
        return profile
    if args.no_content_model:
        return replace(profile, content=None)
    if args.content_cast_only:
        model = with_default(as_cast(model), True)
        profile = replace(profile, content=model)
    if args.content_model:
        model = with_default(model, True)
        profile = replace(profile, content=model)
    if model.apply_by_default:
        say(f"content model: {describe(model)} (--no-content-model turns it off)")
    return profile


def _pair_notes(records) -> list:
    """What the user should know about the pairs written: DNGs that are their own clean target."""
    own = sum(1 for r in records if "pair" in r and r["pair"].get("clean") == r["output"])
    if not own:
        return []
    return [f"{own} DNG(s) have no noise (--no-noise): each is its own clean target, written once "
            "(the manifest's pair.clean names the DNG)"]


def body(args) -> int:
    from g2r_jax.profile import schema as profile_module
    from g2r_jax.batch.conversion import IMAGE_EXTENSIONS, ConvertOptions, convert_files
    from g2r_jax.examples import EXAMPLE_SCENE
    from g2r_jax.io.images import list_inputs

    say = (lambda line: None) if args.quiet else (lambda line: print(f"g2r-convert: {line}", file=sys.stderr))
    if args.example:
        inputs = [EXAMPLE_SCENE] + list(args.inputs)
        profile_name = args.profile or DEFAULT_EXAMPLE_PROFILE
    else:   # inputs and --profile: checked while parsing (check_arguments)
        profile_name = args.profile
    profile = profile_module.load_profile(profile_name)   # validated before any input is read
    if args.example:
        say(f"example scene with profile {profile_name!r}"
            f"{' (the default; --profile NAME picks another)' if not args.profile else ''}")
    if not args.no_noise and not (float(profile.noise.shot.max()) > 0 or float(profile.noise.read.max()) > 0):
        print(f"g2r-convert: warning: profile {shown(profile_name)} has no noise model (shot and read noise are 0): "
              "the DNGs will be noise-free; fit the noise with g2r-fit-profile (NoiseProfile tags, the pixels, or "
              "--noise-table)", file=sys.stderr)
    profile = _content_choice(profile, args, say)
    if args.colour != "matrix" and profile.spectral is None:
        from g2r_jax.profile.editing import attach_spectral

        profile = attach_spectral(profile)
        print(f"g2r-convert: profile {profile.info.name!r} has no sensitivities; using ones "
              f"{profile.spectral.source}", file=sys.stderr)
    errors = []
    files = []
    for item in inputs if args.example else args.inputs:
        try:
            files += list_inputs([item], IMAGE_EXTENSIONS)
        except Exception as error:  # noqa: BLE001 - report and go on with the other inputs
            errors.append(error_message(error))
    files = sorted(set(files), key=lambda p: (p.name, str(p)))
    neutrals = None
    if args.illuminants:
        neutrals = read_illuminant_csv(args.illuminants)
        if len(neutrals) < len(files):
            raise ValueError(f"{args.illuminants}: {len(neutrals)} illuminants for {len(files)} inputs")
    options = ConvertOptions(seed=args.seed, iso=args.iso, noise=not args.no_noise, effects=not args.no_effects,
                             transfer=args.transfer, recipe=args.recipe, colour=args.colour, batch_size=args.batch_size,
                             workers=args.workers, crop_odd=args.crop_odd, lens_shading=args.lens_shading,
                             compression=args.compression, pairs=args.pairs or args.developed,
                             developed=args.developed,
                             max_pixels=int(args.max_megapixels * 1e6) if args.max_megapixels > 0 else None,
                             max_batch_pixels=int(args.max_batch_megapixels * 1e6) if args.max_batch_megapixels > 0 else None,
                             progress=not args.quiet and sys.stderr.isatty())
    for line in errors:
        print(f"g2r-convert: error: {one_line(line)}", file=sys.stderr)
    report = lambda line: print(f"g2r-convert: error: {one_line(line)}", file=sys.stderr)
    if args.engine == "ray":
        from g2r_jax.batch.distributed import convert_files_ray
        result = convert_files_ray(files, profile, args.output, neutrals=neutrals, options=options, on_error=report)
    else:
        result = convert_files(files, profile, args.output, neutrals=neutrals, options=options, on_error=report)
    failed = len(errors) + len(result.errors)
    for note in result.notes + _pair_notes(result.records):
        say(f"note: {one_line(note)}")
    manifest = args.output / "manifest.jsonl"
    print(f"g2r-convert: {len(result.records)} DNG(s) written to {args.output} with profile "
          f"{profile.info.name!r}; {failed} failed; manifest: {manifest if result.records else 'none (nothing written)'}")
    if result.records:
        say(RENDERER_NOTE)
    return 1 if failed else 0


def main(argv=None) -> int:
    return run_command("g2r-convert", body, argv, build_parser(), check_arguments)


if __name__ == "__main__":
    sys.exit(main())
