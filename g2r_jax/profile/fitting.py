"""Fitting a SensorProfile from the tags of real DNGs (or from a list of measured illuminants).

Tags alone are enough: colour matrices and calibration illuminants, CFA layout and levels,
as-shot neutrals (the illuminant population), NoiseProfile with ISO (the noise model) and the
lens-shading opcode lists. Where the matrices differ from file to file (phones often write a
per-shot matrix), the CCT-interpolated pair that best explains them is fitted with optimistix.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from g2r_jax.colour import dng_model as _dng
from g2r_jax.colour.spectrum_locus import distance_outside_locus, is_light_chromaticity
from g2r_jax.runtime.x64 import enable_x64
from g2r_jax.illuminants import choice as _illuminant_choice
from g2r_jax.illuminants import distributions as _illuminants
from g2r_jax import sensor as _sensor
from g2r_jax.io.dng_info import DngInfo, DngError
from g2r_jax.profile.schema import ProfileInfo, SensorProfile, parse_cfa


def colour_model_from_info(info: DngInfo, dtype=np.float32) -> _dng.DngColourModel:
    """The DNG colour model of one file's tags (raises DngError naming the file)."""
    if not info.color_matrices:
        raise DngError(info.path, "no ColorMatrix tags: the camera's colour cannot be modelled")
    try:
        return _dng.DngColourModel.from_tags(info.calibration_illuminants, info.color_matrices,
                                             info.camera_calibrations, info.forward_matrices,
                                             info.analog_balance, dtype=dtype,
                                             illuminant_data=getattr(info, "illuminant_data", ()))
    except ValueError as error:
        raise DngError(info.path, str(error)) from None


def as_shot_neutral(info: DngInfo) -> np.ndarray | None:
    """The file's as-shot neutral (G = 1): AsShotNeutral, or AsShotWhiteXY through the model."""
    if info.as_shot_neutral is not None:
        neutral = np.asarray(info.as_shot_neutral, np.float64)
        return neutral / neutral[1]
    if info.as_shot_white_xy is not None:
        model = colour_model_from_info(info, np.float64)
        return np.asarray(_dng.xy_to_camera_neutral(jnp.asarray(info.as_shot_white_xy, jnp.float64), model))
    return None


def check_file_colour(info: DngInfo) -> DngInfo:
    """Per-file check before any folder-wide fit: this file's colour model and the white point of
    its as-shot neutral (the DNG fixed point, spec 'Colour') must solve to the chromaticity of a
    light: inside the spectrum locus, up to `spectrum_locus.LOCUS_MARGIN` (sodium lamps sit on the
    locus, and a 3x3 matrix puts them slightly beyond it). A solver failure, a non-finite result or a
    white point no light can have raises DngError naming this file, so one bad file never reaches
    the solvers shared by the folder (`fit_color_matrix_pair`)."""
    try:
        with enable_x64():
            model = colour_model_from_info(info, np.float64)
            neutral = as_shot_neutral(info)
            if neutral is None:
                return info
            xy, _ = _dng.camera_neutral_to_xy(jnp.asarray(neutral), model)
            xy = np.asarray(xy, np.float64)
            matrix = np.asarray(_dng.matrix_XYZ_to_camera(jnp.asarray(xy), model))
    except DngError:
        raise
    except Exception as error:  # noqa: BLE001 - solver/XLA errors become one line about this file
        raise DngError(info.path, "AsShotNeutral with the colour matrices: the white-point solver fails "
                                  f"({type(error).__name__})") from error
    if not (np.all(np.isfinite(xy)) and np.all(np.isfinite(matrix))):
        raise DngError(info.path, "AsShotNeutral with the colour matrices: no valid white point")
    if not is_light_chromaticity(xy):
        where = (f"is {distance_outside_locus(xy):.3f} outside the spectrum locus" if min(xy) > 0
                 else "has a coordinate <= 0")
        raise DngError(info.path, f"AsShotNeutral with the colour matrices: white point xy ({xy[0]:.3f}, {xy[1]:.3f}) "
                                  f"{where}: no light has it")
    return info


def camera_key(info: DngInfo) -> tuple:
    """What makes two files the same camera for one profile: the camera model and the set of
    calibration illuminants (whatever the tag order: the fit pairs each matrix with its own)."""
    return (info.unique_camera_model or info.model or "", tuple(sorted(info.calibration_illuminants)))


def choose_camera(infos: list[DngInfo]) -> tuple[list[DngInfo], dict, str | None]:
    """The files of the one camera to fit when `infos` come from several.

    Cameras are ranked by their number of files with decodable pixel data (a header-only file has
    colour tags but neither noise nor levels to check), then by their number of files, then by
    name, so the choice never depends on the order of the files.

    **Returns:** (the chosen camera's files, {camera key: its files} for each camera left out, one
    line saying which camera was chosen and why, or None when there was only one camera).
    """
    groups = {}
    for info in infos:
        groups.setdefault(camera_key(info), []).append(info)
    if len(groups) <= 1:
        return list(infos), {}, None

    def decodable(members):
        return sum(getattr(i, "pixel_data_problem", None) is None for i in members)

    def describe(key):
        members = groups[key]
        return f"{key[0] or 'unnamed'} ({len(members)} file(s), {decodable(members)} with decodable pixels)"

    ranked = sorted(groups, key=lambda k: (-decodable(groups[k]), -len(groups[k]), k))
    keep, runner_up = ranked[0], ranked[1]
    if decodable(groups[keep]) > decodable(groups[runner_up]):
        why = "the most files with decodable pixels"
    elif len(groups[keep]) > len(groups[runner_up]):
        why = "as many files with decodable pixels as the next, and the most files"
    else:
        why = "a tie in decodable and in all files, settled by camera name"
    line = (f"{len(groups)} cameras in the input; fitting {describe(keep)}: {why}; left out: "
            + ", ".join(describe(k) for k in ranked[1:]))
    return groups[keep], {k: groups[k] for k in ranked[1:]}, line


def levels_from_infos(infos) -> tuple[np.ndarray, float, str | None]:
    """The levels a profile holds: the median black level per CFA tile position and the median
    white level over the files (per-file levels are normal for cameras that measure black from
    masked pixels per shot). Returns (black (4,), white, note) where `note` is one line when the
    files' levels differ, else None."""
    blacks = np.stack([np.resize(np.asarray(i.black_level, np.float64).reshape(-1), 4) for i in infos])
    whites = np.array([float(i.white_level) for i in infos])
    notes = []
    if np.ptp(blacks, axis=0).max() > 0:
        low, high = np.argmin(blacks.mean(axis=1)), np.argmax(blacks.mean(axis=1))
        notes.append(f"black levels differ between files ({blacks.min():g} to {blacks.max():g} DN; lowest in "
                     f"{Path(infos[low].path).name}, highest in {Path(infos[high].path).name})")
    if np.ptp(whites) > 0:
        notes.append(f"white levels differ between files ({whites.min():g} in {Path(infos[int(np.argmin(whites))].path).name}"
                     f" to {whites.max():g} in {Path(infos[int(np.argmax(whites))].path).name})")
    note = ("; ".join(notes) + "; the profile holds the median of each") if notes else None
    return np.median(blacks, axis=0), float(np.median(whites)), note


def _same_matrices(infos) -> bool:
    """Do all files hold the same matrices (compared per illuminant, whatever the tag order)?"""
    with enable_x64():
        models = [colour_model_from_info(i, np.float64) for i in infos]
    first = np.asarray(models[0].color_matrix)
    return all(m.calibration_illuminants == models[0].calibration_illuminants and
               np.allclose(np.asarray(m.color_matrix), first, atol=1e-6) for m in models)


PAIR_REGULARISATION = 1e-3   # weight of the pull towards the reference file's matrices


def fit_color_matrix_pair(infos, dtype=np.float32) -> _dng.DngColourModel:
    """One set of ColorMatrices (one per calibration illuminant) explaining files whose matrices differ.

    For each file i, its effective XYZtoCamera at its own as-shot white (from its own tags) is
    the target; the shared matrices, interpolated at each file's white with the DNG weights
    (mired for two illuminants, the SDK's triple weights for three), are fitted by
    Levenberg-Marquardt (optimistix) over all files. Each fitted matrix keeps its illuminant.
    """
    with enable_x64():
        targets, weights = [], []
        for info in infos:
            model = colour_model_from_info(info, np.float64)
            neutral = as_shot_neutral(info)
            neutral = np.ones(3) if neutral is None else neutral
            xy, _ = _dng.camera_neutral_to_xy(jnp.asarray(neutral), model)
            weights.append(np.asarray(_dng.illuminant_weights(xy, model)))
            targets.append(np.asarray(_dng.matrix_XYZ_to_camera(xy, model)))
        targets, weights = jnp.asarray(np.stack(targets)), jnp.asarray(np.stack(weights))
        reference = colour_model_from_info(infos[0], np.float64)

        start = reference.color_matrix

        def residuals(matrices, _):
            predicted = jnp.einsum("fk,kij->fij", weights, matrices)
            # Tikhonov term towards the reference file's matrices: files shot at nearly one white
            # leave the matrices' difference undetermined, and the solver must not wander along it
            # (fuzzing found a fitted matrix with a negative response to white this way).
            return jnp.concatenate([(predicted - targets).reshape(-1),
                                    PAIR_REGULARISATION * (matrices - start).reshape(-1)])

        solver = optx.LevenbergMarquardt(rtol=1e-10, atol=1e-12)
        solution = optx.least_squares(residuals, solver, start, max_steps=200)
        fitted = np.asarray(solution.value)
    tags = reference.dng_tags()   # the reference file's sets, in the model's order
    n = len(tags["calibration_illuminants"])
    return _dng.DngColourModel.from_tags(tags["calibration_illuminants"], list(fitted[:n]),
                                         tags["camera_calibrations"], tags["forward_matrices"],
                                         infos[0].analog_balance, dtype=dtype,
                                         illuminant_data=tags["illuminant_data"])


def noise_from_infos(infos, cfa_pattern, dtype=np.float32) -> _sensor.NoiseModel:
    """NoiseModel from the files' NoiseProfile tags, grouped by ISO (median per ISO).

    NoiseProfile holds (S, O) per colour plane (or one pair for all), in normalised units
    (DNG spec 1.6, NoiseProfile): variance = S x + O; mapped to tile positions by the CFA.
    Files without a usable NoiseProfile (missing, all zero, a term <= 0) get their noise
    measured from their own pixels, with a warning (`g2r_jax.sensor.noise.fallback`).
    """
    from g2r_jax.sensor.noise.fallback import noise_and_source

    return noise_and_source(infos, cfa_pattern, dtype)[0]


PRIOR_KINDS = _illuminant_choice.PRIOR_KINDS
ILLUMINANTS_PROVENANCE = "; illuminants: "   # before the illuminant model's reason in a fitted profile's provenance


def illuminant_model_for(chromaticities, colour_model, kind: str = "auto", seed: int = 0,
                         dtype=np.float32) -> _illuminants.IlluminantModel:
    """Fit the illuminant model `kind` to the measured lights (r/g, b/g) of one camera.

    `kind`: one of `illuminants.choice.KINDS`: 'kernel' (a kernel density of the lights along
    the camera's Planckian locus, blended with the cross-camera prior), 'pooled' (the same kernel
    blended with other cameras' measured lights carried into this camera), 'gaussian' (published),
    'mixture' (BIC-selected), 'locus' (supplement S3), 'prior', 'prior-night', 'prior-day-night',
    or 'auto', which takes the kernel model from `illuminants.choice.MIN_LIGHTS_FOR_KERNEL` (10)
    distinct measured lights on and 'pooled' below (the prior with a night preset where the lights
    strongly favour one): chosen by the downstream measurement (an illuminant estimator trained on
    g2r_jax RAW of CG frames, tested on the real NUS images; benchmarks/few_lights.py,
    docs/pages/validation/illuminant_models.md).
    `illuminants.choice.choose_illuminant_model` gives the same model with the reason for it.
    """
    return _illuminant_choice.choose_illuminant_model(chromaticities, colour_model, kind, seed, dtype).model


def fit_profile(infos: list[DngInfo], *, name: str = "fitted", illuminant_model: str = "auto",
                noise: _sensor.NoiseModel | None = None, chromaticities=None, provenance: str = "",
                seed: int = 0, dtype=np.float32, notes: list | None = None) -> SensorProfile:
    """Fit a SensorProfile from DNG tags.

    **Arguments:** `infos`: tags of the camera's DNGs (`g2r_jax.io.dng_read.read_dng_info`);
    `illuminant_model`: see `illuminant_model_for`; `noise`: a NoiseModel overriding the files'
    NoiseProfile tags (e.g. from a calibration table), used as given (a read term measured from
    integer raws goes through `sensor.noise.quantisation.without_quantisation` first; the files'
    own noise does here); `chromaticities`: (N, 2) illuminants in
    (r/g, b/g) to use instead of the files' as-shot neutrals; `provenance`: where the numbers
    came from (stored in the profile); `notes`: a list that gets one line per thing a user should
    know (the dark frames found and what was taken from them).

    Dark frames among `infos` (recognised from their pixels, `g2r_jax.measure.dark_frames`) give
    the read noise of their ISO and the black level, and take no part in the colour, illuminant
    and exposure fits (they have no scene and no meaningful as-shot neutral).

    **Returns:** a `SensorProfile`. Raises DngError for files without usable colour tags.
    """
    if not infos:
        raise ValueError("no DNG files to fit a profile from")
    reference = infos[0]
    for info in infos:
        if not info.color_matrices:
            raise DngError(info.path, "no ColorMatrix tags: the camera's colour cannot be modelled")
        if not info.is_cfa:
            raise DngError(info.path, "LinearRaw (demosaiced) DNG: no CFA layout to simulate")
        if sorted(info.calibration_illuminants) != sorted(reference.calibration_illuminants):
            raise DngError(info.path, f"calibration illuminants {info.calibration_illuminants} differ from "
                                      f"{reference.path}'s {reference.calibration_illuminants}")
    dark_frames, scenes = [], infos
    if noise is None or chromaticities is None:
        from g2r_jax.measure.dark_frames import find_dark_frames

        scenes, dark_frames = find_dark_frames(infos)
        infos = scenes or infos    # only dark frames: their tags still give the colour and levels
        reference = infos[0]
    try:
        cfa = parse_cfa(reference.cfa_pattern)
    except ValueError as error:
        raise DngError(reference.path, str(error)) from None
    colour_model = (colour_model_from_info(reference, dtype) if _same_matrices(infos)
                    else fit_color_matrix_pair(infos, dtype))
    if chromaticities is None:
        neutrals = [n for n in (as_shot_neutral(i) for i in infos) if n is not None]
        chromaticities = (_illuminants.neutral_to_chromaticity(np.stack(neutrals)) if neutrals
                          else np.zeros((0, 2)))
    chosen = _illuminant_choice.choose_illuminant_model(chromaticities, colour_model, illuminant_model, seed, dtype)
    illuminants, illuminant_reason = chosen.model, chosen.reason   # the reason states the lights' shares
    noise_source = ""
    black, white, _ = levels_from_infos(infos)   # the CLI reports the note
    if noise is None:
        from g2r_jax.sensor.noise.fallback import noise_and_source
        from g2r_jax.sensor.noise.quantisation import without_quantisation

        noise, noise_source = noise_and_source(scenes, cfa, dtype, dark_frames=dark_frames)
        # NoiseProfile tags and pixel measurements are of integer raws: rounding counted once
        noise = without_quantisation(noise, black, white)
        noise_source += "; read term without the 1/12 DN^2 rounding, which the simulation adds"
    effects = _sensor.no_effects(dtype)
    if dark_frames:
        effects, line = _with_dark_frame_black(effects, dark_frames, black, dtype)
        noise_source = "; ".join(filter(None, [noise_source, line]))
        if notes is not None:
            notes.append(dark_frame_note(dark_frames, used_for_noise="read term from" in noise_source))
    opcodes = tuple(sorted((k, bytes(v).hex()) for k, v in (reference.opcode_lists or {}).items()))
    info = ProfileInfo(name=name, unique_camera_model=reference.unique_camera_model or reference.model or name,
                       make=reference.make, model=reference.model,
                       calibration_illuminants=colour_model.calibration_illuminants,   # the model's order
                       provenance=" ".join(filter(None, [provenance or f"fitted by g2r_jax from {len(infos)} DNG file(s)",
                                                         noise_source and f"({noise_source})"]))
                       + ILLUMINANTS_PROVENANCE + illuminant_reason,
                       opcode_lists=opcodes)
    baseline = float(np.median([i.baseline_exposure for i in infos]))
    return SensorProfile(
        cfa_pattern=jnp.asarray(cfa, jnp.int32), black_level=jnp.asarray(black, dtype),
        white_level=jnp.asarray(white, dtype),
        baseline_exposure=jnp.asarray(baseline, dtype), colour=colour_model, illuminants=illuminants,
        exposure=_sensor.fixed_exposure(dtype), noise=noise, effects=effects, info=info)


PEDESTAL_MIN_DN = 0.1   # a dark frames' black this far (and 3 standard errors) from the tag becomes a pedestal


def _with_dark_frame_black(effects, dark_frames, black, dtype):
    """(effects with the dark frames' black pedestal where they put black away from the tags'
    median `black`, a provenance line or ""). The pedestal is the pixel-weighted mean level of all
    dark frames minus the tag per CFA site, kept where it exceeds PEDESTAL_MIN_DN and 3 standard
    errors (between frames when there are 3 or more: a dark level drifts with temperature)."""
    from g2r_jax.profile import schema as _profile

    means = np.stack([stats.mean for _, stats in dark_frames])
    counts = np.stack([stats.count for _, stats in dark_frames])
    variances = np.stack([stats.variance for _, stats in dark_frames])
    offset = (counts * means).sum(axis=0) / counts.sum(axis=0) - black
    se = np.sqrt((variances / counts).sum(axis=0)) / len(dark_frames)
    if len(dark_frames) >= 3:
        se = np.maximum(se, means.std(axis=0, ddof=1) / np.sqrt(len(dark_frames)))
    if not np.any((np.abs(offset) >= PEDESTAL_MIN_DN) & (np.abs(offset) > 3 * se)):
        return effects, ""
    pedestal = offset
    effects = _profile.replace(effects, black_pedestal=jnp.asarray(pedestal, dtype))
    return effects, ("black pedestal from the dark frames: " + " ".join(f"{v:+.2f}" for v in pedestal)
                     + " DN per CFA site above the BlackLevel tags")


def dark_frame_note(dark_frames, *, used_for_noise: bool) -> str:
    """One line for the user: how many dark frames, what was taken from them."""
    from g2r_jax.sensor.noise.fallback import dark_frames_by_iso

    names = [Path(info.path).name for info, _ in dark_frames]
    shown = ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")
    by_iso = dark_frames_by_iso(dark_frames)
    sigma = "; ".join(f"ISO {iso:g}: " + " ".join(f"{np.sqrt(v):.2f}" for v in found.variance_dn2)
                      for iso, found in sorted(by_iso.items()))
    banding = max(float(np.max(found.banding_share)) for found in by_iso.values())
    hot = max(found.hot_fraction for found in by_iso.values())
    what = ("took the read noise per CFA site from them" if used_for_noise
            else "left them out of the colour and illuminant fits (the noise came from elsewhere)")
    extra = []
    if banding >= 0.1:
        extra.append(f"{banding:.0%} of their variance is row/column banding, simulated as pixel noise")
    if hot > 0:
        extra.append(f"{hot:.2g} of their pixels hot, left out")
    return (f"{len(names)} dark frame(s) ({shown}): {what} (sd {sigma} DN)"
            + "".join(f"; {e}" for e in extra) + "; they take no part in the colour and illuminant fits")


def content_model_of_dngs(infos, colour_model, *, on_error=None) -> tuple:
    """The content model `g2r-fit-profile` fits to DNGs' scenes (`g2r_jax.content`, family
    'scenes': each CG frame's grey-world cast and brightness those of one of the files' scenes,
    drawn per frame, the casts re-centred on their median shrunk toward the prior of real scenes
    by their number; each distinct scene once, so that a burst is one scene), applied
    by default.

    **Arguments:** `infos`: `DngInfo`s of the files; `colour_model`: the camera's
    `DngColourModel`; `on_error(info, problem)`: told of each file that cannot be used.
    **Returns:** (model or None, files used, why there is none: '' with a model).
    """
    from g2r_jax.content import content_model_from_files, with_default
    from g2r_jax.io.dng_read import read_dng_pixels

    def read(info):
        return read_dng_pixels(info.path, info), info.cfa_pattern, info.black_level, info.white_level, as_shot_neutral(info)

    try:
        model, used = content_model_from_files(infos, read, colour_model=colour_model, on_error=on_error,
                                               family="scenes")
    except ValueError as error:    # e.g. a median cast outside sRGB at the files' light: no model, said
        return None, 0, str(error)
    if model is None:
        return None, 0, "no file gave scene statistics"
    return with_default(model, True), used, ""
