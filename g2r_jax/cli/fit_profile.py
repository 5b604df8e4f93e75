"""g2r-fit-profile: fit a sensor profile from a folder of the camera's DNGs (or an illuminant list)."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from g2r_jax.cli.common import (
    add_common_flags, command_parser, error_message, one_line, output_file_problem, required_group,
    run_command, shown)


def validate_profile(profile, path) -> None:
    """The loader's validation of `profile` as it would be written to `path` (ProfileError)."""
    import numpy as np

    from g2r_jax.runtime.x64 import enable_x64
    from g2r_jax.profile.schema import profile_from_dict, profile_to_dict

    with enable_x64():
        profile_from_dict(profile_to_dict(profile), str(path), np.float64)


EXAMPLES = """  g2r-fit-profile my_camera_dngs/ -o my_camera.json
  g2r-fit-profile --illuminants lamps.csv --calibration one_shot.dng -o night.json --noise-table noise.csv
"""


def build_parser() -> argparse.ArgumentParser:
    parser = command_parser("g2r-fit-profile", __doc__, EXAMPLES)
    parser.add_argument("dng_dirs", nargs="*", type=Path, metavar="DNG_DIR",
                        help="folders (or files) of the camera's DNGs (not needed with --illuminants)")
    required_group(parser).add_argument("-o", "--output", required=True, type=Path, metavar="PROFILE_JSON",
                                        help="profile JSON to write (its folder must exist)")
    parser.add_argument("--illuminants", type=Path, metavar="CSV",
                        help="CSV of measured illuminants (r_over_g,g,b_over_g) instead of as-shot neutrals")
    parser.add_argument("--calibration", type=Path, metavar="DNG|JSON",
                        help="DNG (or profile JSON) giving the colour matrices, CFA and levels (with --illuminants)")
    parser.add_argument("--illuminant-model", default="auto",
                        choices=["auto", "kernel", "pooled", "gaussian", "mixture", "locus", "prior", "prior-night",
                                 "prior-day-night"],
                        help="auto: 'kernel' from 10 distinct measured illuminants on (a kernel density of the lights "
                             "along the camera's Planckian locus, blended with the cross-camera prior), else 'pooled' "
                             "(chosen by the downstream measurement of docs validation/illuminant_models; 'prior' with "
                             "a night preset where 5 or more lights strongly favour one); the illuminant line says "
                             "how much the files' lights weigh in the model and how much the rest; "
                             "'gaussian': the published Gaussian + convex hull; 'mixture': Gaussians by BIC + hull; "
                             "'prior': the camera-independent prior of measured day lights (-night / -day-night "
                             "presets); 'pooled': the lights' kernel density on other cameras' measured lights "
                             "carried through this camera's matrices; 'locus': the A-D65 CCT locus of the "
                             "calibration matrices (supplement S3)")
    parser.add_argument("--noise-table", type=Path, metavar="CSV",
                        help="noise calibration CSV (iso,cfa_channel_index,beta1_shot,beta2_read; DN incl. black)")
    parser.add_argument("--sensitivities", type=Path, metavar="FILE",
                        help="the camera's measured spectral sensitivities (rawtoaces JSON, camspec text, or CSV "
                             "wavelength,r,g,b), stored in the profile for --colour spectral")
    parser.add_argument("--sensitivities-camera", help="camera name inside a camspec file with several cameras")
    parser.add_argument("--name", help="profile name (default: the output file's stem)")
    parser.add_argument("--no-content-model", action="store_true",
                        help="do not fit the content model (each CG frame's colour cast and brightness taken to "
                             "those of one of the DNGs' scenes; applied by default, see docs validation/content_model)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the mixture model's initialisation")
    add_common_flags(parser)
    return parser


def check_arguments(args) -> str | None:
    """The first problem of the arguments found without reading any DNG (None when there is none)."""
    if args.illuminants and not args.calibration:
        return "--illuminants needs --calibration DNG (or profile JSON) for the camera's matrices"
    if not args.illuminants and not args.dng_dirs:
        return "no DNG_DIR given (folders or files of the camera's DNGs), or use --illuminants CSV --calibration DNG"
    for option in ("illuminants", "calibration", "noise_table", "sensitivities"):
        path = getattr(args, option)
        if path is not None and not path.is_file():
            return f"--{option.replace('_', '-')} {path}: no such file"
    return output_file_problem("-o", args.output)


def read_noise_table(path: Path, black_level, white_level):
    """NoiseModel from a calibration CSV like ../shared/data/noise/ (errors name the file), its read
    term less the rounding variance (`sensor.noise.quantisation`)."""
    from g2r_jax.profile.schema import noise_from_table
    from g2r_jax.io.noise_table import read_noise_table_rows

    isos, beta1, beta2 = read_noise_table_rows(path, black_level, white_level)   # checked row by row
    from g2r_jax.sensor.noise.quantisation import without_quantisation

    # a calibration of integer raws (photon transfer): its read term holds the rounding, which the simulation adds
    return without_quantisation(noise_from_table(isos, beta1, beta2, black_level, white_level), black_level, white_level)


def _calibration_infos(path: Path):
    from g2r_jax.io.dng_read import read_dng_info
    from g2r_jax.profile.schema import load_profile
    from g2r_jax.io.dng_info import DngInfo
    import numpy as np

    if path.suffix.lower() == ".json":
        profile = load_profile(path, dtype=np.float64)
        return [DngInfo(path=str(path), cfa_pattern=tuple(int(c) for c in np.asarray(profile.cfa_pattern)),
                        black_level=np.asarray(profile.black_level), white_level=float(profile.white_level),
                        unique_camera_model=profile.info.unique_camera_model,
                        **profile.colour.dng_tags())]
    return [read_dng_info(path)]


def _one_camera(infos, failures, quiet=False):
    """Keep the files of one camera (`choose_camera`: the most files with decodable pixels); say
    which and why, and report every other camera's files as failures rather than mixing two
    cameras' colour in one profile."""
    from g2r_jax.profile.fitting import choose_camera

    kept, left_out, line = choose_camera(infos)
    if line and not quiet:
        print(f"g2r-fit-profile: note: {one_line(line)}", file=sys.stderr)
    for key, members in left_out.items():
        failures += [one_line(f"{i.path}: left out: a different camera ({key[0] or 'unnamed'}, calibration "
                              f"illuminants {key[1]}) from the {len(kept)} file(s) of "
                              f"{kept[0].unique_camera_model or kept[0].model or 'unnamed'} being fitted")
                     for i in members]
    return kept


def _with_sensitivities(profile, path, camera, chromaticities, infos):
    """The profile with measured sensitivities and the lamp families its illuminants demand
    (from the measured illuminant CSV or the DNGs' as-shot neutrals)."""
    import numpy as np

    from g2r_jax.illuminants.distributions import neutral_to_chromaticity
    from g2r_jax.io.sensitivities import read_sensitivities
    from g2r_jax.profile.editing import attach_spectral

    sensitivities = read_sensitivities(path, camera)
    if chromaticities is None:
        neutrals = [info.as_shot_neutral for info in infos if getattr(info, "as_shot_neutral", None) is not None]
        chromaticities = neutral_to_chromaticity(np.stack(neutrals)) if len(neutrals) >= 3 else None
    return attach_spectral(profile, sensitivities.values, source=sensitivities.source, chromaticities=chromaticities)


def _read_folder_infos(args, failures):
    """The checked tags of every DNG under `args.dng_dirs` (one camera's, `_one_camera`); each
    unreadable folder or file becomes a line of `failures`."""
    from g2r_jax.io.dng_read import read_dng_info, require_bayer_cfa, require_colour_tags
    from g2r_jax.io.images import list_inputs
    from g2r_jax.profile.fitting import check_file_colour

    paths, infos, warned = [], [], {}
    for item in args.dng_dirs:
        try:
            paths += list_inputs([item], (".dng",))
        except Exception as error:  # noqa: BLE001
            failures.append(str(error))
    for path in paths:
        try:   # every check of one file's tags happens here, before any folder-wide solver
            info = check_file_colour(require_bayer_cfa(require_colour_tags(read_dng_info(path))))
            for warning in info.warnings:
                warned.setdefault(warning, []).append(shown(path))
            infos.append(info)
        except Exception as error:  # noqa: BLE001 - report and go on
            failures.append(error_message(error) if str(path) in str(error) else
                            one_line(f"{path}: {error_message(error)}"))
    for warning, names in warned.items():   # one line per kind of problem, naming its files
        print(f"g2r-fit-profile: warning: {one_line(f'{warning}: {files_named(names)}')}", file=sys.stderr)
    return _one_camera(infos, failures, getattr(args, "quiet", False))


def files_named(names, shown_at_most: int = 10) -> str:
    """'N file(s): a, b, ... and M more': the files one warning line is about."""
    listed = ", ".join(names[:shown_at_most]) + (f" and {len(names) - shown_at_most} more" if len(names) > shown_at_most
                                                 else "")
    return f"{len(names)} file(s): {listed}"


def _gather_inputs(args, failures):
    """(infos, chromaticities, source): the files' tags, the measured illuminants' chromaticities
    (None when the as-shot neutrals of the DNGs stand for them) and the provenance line."""
    from g2r_jax.cli.convert import read_illuminant_csv
    from g2r_jax.illuminants.distributions import neutral_to_chromaticity

    if args.illuminants:
        if not args.calibration:
            raise ValueError("--illuminants needs --calibration DNG (or profile JSON) for the camera's matrices")
        infos = _calibration_infos(args.calibration)
        chromaticities = neutral_to_chromaticity(read_illuminant_csv(args.illuminants))
        return infos, chromaticities, f"illuminants from {args.illuminants.name}, colour tags from {args.calibration.name}"
    if not args.dng_dirs:
        raise ValueError("give DNG folders, or --illuminants CSV --calibration DNG")
    infos = _read_folder_infos(args, failures)
    return infos, None, f"{len(infos)} DNG file(s) from {', '.join(str(d) for d in args.dng_dirs)}"


def _report_dropped(info, error, failures) -> None:
    line = one_line(f"{info.path}: dropped, no valid profile with this file ({error_message(error)})")
    failures.append(line)
    print(f"g2r-fit-profile: error: {line}", file=sys.stderr)


def _fit_without_one(attempt, infos, failures, error):
    """(profile, infos) after dropping the one file whose absence alone gives a valid profile (the
    colour-tag outlier when several would); (None, infos) when no single file does."""
    fits = {}
    for k in range(len(infos)):
        try:
            fits[k] = attempt(infos[:k] + infos[k + 1:], None)
        except Exception:  # noqa: BLE001
            pass
    if len(fits) > 1:   # several files can each be dropped: drop the one whose colour tags disagree
        outlier = colour_outlier(infos, list(fits))
        fits = {outlier: fits[outlier]} if outlier is not None else fits
    if len(fits) != 1:
        return None, infos
    (k, profile), = fits.items()
    _report_dropped(infos[k], error, failures)
    return profile, infos[:k] + infos[k + 1:]


def _fit_survivors(attempt, infos, failures, first_error):
    """(profile, infos) from the files that give a valid profile on their own (several bad files)."""
    survivors = []
    for info in infos:
        try:
            attempt([info], None)
            survivors.append(info)
        except Exception as single:  # noqa: BLE001
            _report_dropped(info, single, failures)
    if not survivors or len(survivors) == len(infos):
        raise ValueError(f"no valid profile from {len(infos)} file(s): {error_message(first_error)}")
    return attempt(survivors, None), survivors


def _fit_dropping_bad_files(attempt, infos, chromaticities, failures):
    """(profile, infos): the fit of all files, or when it fails, of the files left after dropping
    those that break it (one file, else every file that fails on its own)."""
    try:
        return attempt(infos, chromaticities), infos
    except Exception as error:  # noqa: BLE001 - find the files that break the fit, drop them, refit
        if chromaticities is not None or len(infos) < 2:
            raise ValueError(f"no valid profile from {len(infos)} file(s): {error_message(error)}") from error
        first_error = error
    profile, infos = _fit_without_one(attempt, infos, failures, first_error)
    if profile is None:
        profile, infos = _fit_survivors(attempt, infos, failures, first_error)
    return profile, infos


def _noise_from_table(args, infos):
    import numpy as np

    if not args.noise_table:
        return None
    return read_noise_table(args.noise_table, np.resize(np.asarray(infos[0].black_level, float), 4),
                            infos[0].white_level)


def _write_profile(profile, args, infos, failures) -> None:
    from g2r_jax.profile.schema import save_profile

    removed = remove_stale_temporaries(args.output)
    if removed:
        print(f"g2r-fit-profile: note: removed {removed} temporary file(s) of {shown(args.output.name)} left by an "
              "earlier run that was stopped", file=sys.stderr)
    save_profile(profile, args.output)
    print(f"g2r-fit-profile: wrote {args.output} ({illuminant_model_name(profile)} illuminant model, "
          f"{len(infos)} file(s); {len(failures)} failed)")
    if not args.quiet:
        print(f"g2r-fit-profile: illuminant model: {one_line(illuminant_reason(profile))}")


def body(args) -> int:
    from g2r_jax.profile.fitting import fit_profile, levels_from_infos

    failures = []
    infos, chromaticities, source = _gather_inputs(args, failures)
    for line in failures:
        print(f"g2r-fit-profile: error: {one_line(line)}", file=sys.stderr)
    if not infos:
        raise ValueError("no usable DNG files; nothing to fit")
    noise = _noise_from_table(args, infos)
    if noise is not None:
        source += f"; noise from {args.noise_table.name}"
    dark_frame_notes = []   # the last fit's lines on dark frames (`fit_profile(notes=...)`)
    fit_warnings = {}       # each trial fit's warnings: only the kept fit's are shown (not one per trial)

    def attempt(subset, chromaticities_subset):
        """Fit and validate with the loader's own checks (nothing is written yet)."""
        notes = []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            fitted = _fit_and_validate(subset, chromaticities_subset, notes)
        fit_warnings[tuple(i.path for i in subset)] = caught
        return fitted

    def _fit_and_validate(subset, chromaticities_subset, notes):
        fitted = fit_profile(subset, name=args.name or args.output.stem, illuminant_model=args.illuminant_model,
                             noise=noise, chromaticities=chromaticities_subset,
                             provenance=f"g2r-fit-profile: {source}", seed=args.seed, notes=notes)
        validate_profile(fitted, args.output)
        dark_frame_notes[:] = notes
        return fitted

    profile, infos = _fit_dropping_bad_files(attempt, infos, chromaticities, failures)
    for record in fit_warnings.get(tuple(i.path for i in infos), ()):
        warnings.warn_explicit(record.message, record.category, record.filename, record.lineno)
    if chromaticities is None:
        note = levels_from_infos(infos)[2]
        if note and not args.quiet:
            print(f"g2r-fit-profile: note: {one_line(note)}", file=sys.stderr)
    for line in dark_frame_notes if not args.quiet else ():
        print(f"g2r-fit-profile: note: {one_line(line)}", file=sys.stderr)
    if args.sensitivities:
        profile = _with_sensitivities(profile, args.sensitivities, args.sensitivities_camera, chromaticities, infos)
    if chromaticities is None and not args.no_content_model:
        profile = _with_content_model(profile, infos, args)
    _write_profile(profile, args, infos, failures)
    return 1 if failures else 0


def _with_content_model(profile, infos, args):
    """The profile with the content model of its DNGs' scenes (`g2r_jax.profile.fitting.content_model_of_dngs`:
    each CG frame's colour cast and brightness those of one of these files' scenes), fitted
    without labels and applied by default (docs/pages/validation/content_model.md)."""
    from g2r_jax.content import describe
    from g2r_jax.content.fitting import files_weight
    from g2r_jax.profile.fitting import content_model_of_dngs
    from g2r_jax.profile.schema import replace

    skipped = []
    model, used, reason = content_model_of_dngs(infos, profile.colour, on_error=lambda info, problem: skipped.append(info.path))
    if not args.quiet:
        if model is None:
            print(f"g2r-fit-profile: note: no content model ({reason})")
        else:
            weights = "/".join(f"{files_weight(name, used):.0%}" for name in ("cast_red", "cast_blue"))
            print(f"g2r-fit-profile: content model: {describe(model)}, from {used} file(s)' scenes (their median "
                  f"cast weighs {weights} red/blue, the rest the prior of real scenes); applied by default "
                  "(g2r-convert --no-content-model turns it off)"
                  + (f"; {len(skipped)} file(s) too small or without a neutral" if skipped else ""))
    return profile if model is None else replace(profile, content=model)


def illuminant_reason(profile) -> str:
    """Why the profile got its illuminant model and from how many lights (its provenance says)."""
    from g2r_jax.profile.fitting import ILLUMINANTS_PROVENANCE

    return profile.info.provenance.rpartition(ILLUMINANTS_PROVENANCE)[2] or profile.illuminants.kind


def illuminant_model_name(profile) -> str:
    """The illuminant model's name as the user chooses it ('pooled', 'kernel', 'locus', ...): the
    first word of its reason (`illuminants.choice.choose_illuminant_model`); the stored family
    (`IlluminantModel.kind`, 'kernel' for a pooled model too) where the provenance has none."""
    from g2r_jax.illuminants.choice import KINDS

    word = illuminant_reason(profile).split(" ", 1)[0]
    return word if word in KINDS else profile.illuminants.kind


def colour_outlier(infos, candidates):
    """The one file among `candidates` (indices into `infos`) whose colour matrices lie farthest
    from the element-wise median of all files' (files of one camera carry the same or nearly the
    same matrices), or None when no single file stands out."""
    import numpy as np

    def tags(info):
        parts = [np.ravel(np.asarray(m, np.float64))
                 for m in (*info.color_matrices, *info.camera_calibrations, *info.forward_matrices)]
        return np.nan_to_num(np.concatenate(parts)) if parts else np.zeros(0)

    vectors = [tags(info) for info in infos]
    if len(infos) < 3 or len({v.size for v in vectors}) != 1 or vectors[0].size == 0:
        return None
    median = np.median(np.stack(vectors), axis=0)
    distance = {k: float(np.max(np.abs(vectors[k] - median))) for k in candidates}
    ranked = sorted(distance.values(), reverse=True)
    if ranked[0] > 0 and (len(ranked) == 1 or ranked[0] > ranked[1]):
        return max(distance, key=distance.get)
    return None


def remove_stale_temporaries(output: Path) -> int:
    """Remove the temporaries ('.<name>.<random>.tmp', see `g2r_jax.io.atomic`) of `output` that a
    killed run left beside it; their count."""
    import glob

    from g2r_jax.io.atomic import remove_temporaries

    try:
        return remove_temporaries(list(output.parent.glob(f".{glob.escape(output.name)}.*")))
    except OSError:
        return 0


def main(argv=None) -> int:
    return run_command("g2r-fit-profile", body, argv, build_parser(), check_arguments)


if __name__ == "__main__":
    sys.exit(main())
