"""The noise model of a profile fitted from DNGs: NoiseProfile tags where usable, otherwise the
noise measured from the files' own pixels, and always a statement of where it came from.

Issue 8: DNGs without NoiseProfile (e.g. Canon 350D conversions) or with an all-zero one (Nexus
5X) gave a profile with no noise at all, at ISO 100 whatever the files said; a read-noise term of
0 (Samsung S6 edge) was used as is. Here, per file:

- `ok`: NoiseProfile with S > 0 and O > 0 for every plane: used (median per ISO, as before).
- `missing`, `zero` (all terms 0) or `degenerate` (a term <= 0 or not finite): the noise level
  function is measured from the file's pixels where LibRaw decodes them
  (`sensor.noise.estimation.estimate_noise_level_function`) and fitted by S x + O per CFA position
  (`sensor.noise.extension.fit_shot_read`); a degenerate tag whose pixels cannot be decoded is kept
  with O raised to the rounding variance 1/12 DN^2 (the least noise a quantised raw has).
- An ISO with tag rows uses them; measured rows fill ISOs without. Every file's ISO is kept
  (files without an ISO count as 100). Nothing usable at all: a noiseless model at the files'
  ISOs, with a loud warning.

Dark frames (`g2r_jax.measure.dark_frames`, issue 29) give the read term of their ISO directly:
it replaces the read term of the tags or of the measurement at that ISO, and the measured shot
term is refitted with the read term held there (`measure_pooled(fixed_read=...)`). Dark frames
never enter the pooled flat blocks: their blocks' means are noise, and the bins they fall in
(those whose mean noise lifted above 2^-11 of the range) put read-noise variance at a signal
that is not there, lowering the fitted intercept by shot x that signal (x0.84 at ISO 1600 on the
S20 FE-like sensor of `benchmarks/read_noise_dark_frames.py`).

One warning line names the files concerned; `source` (for the profile's provenance) says where
the noise came from.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from g2r_jax.sensor.noise import estimation as _estimation
from g2r_jax.sensor.noise import extension as _extension
from g2r_jax import sensor as _sensor


def classify_noise_profile(info) -> str:
    """'ok', 'missing', 'zero' or 'degenerate' for one file's NoiseProfile tag."""
    if info.noise_profile is None:
        return "missing"
    pairs = np.asarray(info.noise_profile, np.float64).reshape(-1)
    if pairs.size == 0:
        return "missing"
    if np.all(pairs == 0):
        return "zero"
    if not np.all(np.isfinite(pairs)) or np.any(pairs <= 0):
        return "degenerate"
    return "ok"


def _tag_per_position(info, cfa_pattern) -> np.ndarray:
    pairs = np.asarray(info.noise_profile, np.float64).reshape(-1, 2)
    per_colour = np.repeat(pairs, 3, axis=0) if len(pairs) == 1 else pairs[:3]
    return per_colour[np.asarray(cfa_pattern)]


def _levels(info):
    black = np.resize(np.asarray(info.black_level, np.float64).reshape(-1), 4)
    return black, float(info.white_level)


BURST_PIXELS = 150_000_000   # the frames a burst check holds in memory at once (uint16: 300 MB)


def measure_pooled(infos, *, n_bootstrap: int = 50, fixed_read=None, methods: list | None = None):
    """(shot (4,), read (4,)) per tile position measured from the pixels of several DNGs of one
    ISO and one black/white level, their flat blocks pooled into one noise level function (the
    audit's estimator, `estimation.estimate_noise_level_function`, on the blocks of every file:
    small files have too few flat blocks each, not together), or None when no file decodes or
    the pooled blocks are too few; and the [(file name, reason)] of the files that failed.
    `fixed_read` (4,), normalised with the rounding in it (e.g. from dark frames): the read term,
    only the shot term is fitted (`shot_with_read_held`).

    Files that form a static burst (`measure.bursts.is_static_burst`: the same scene in every
    frame) are measured over time instead (`measure.photon_transfer.temporal_bins` and
    `fit_shot_read`): no scene texture, and a
    read term unbiased at the low end; `methods` (a list) gets "temporal" or "flat blocks"."""
    from g2r_jax.io.dng_read import read_dng_pixels
    from g2r_jax.measure import photon_transfer as _photon_transfer
    from g2r_jax.measure.bursts import is_static_burst
    from g2r_jax.sensor.noise.estimation import to_normalised_planes

    blocks, problems, levels, mosaics, held = [], [], None, [], 0
    for info in infos:
        try:
            mosaic = read_dng_pixels(info.path, info)
        except Exception as error:  # noqa: BLE001 - DngError and anything LibRaw raises: reported, not fatal
            problems.append((Path(info.path).name, str(getattr(error, "problem", error))))
            continue
        levels = levels or _levels(info)
        blocks.append(_estimation.block_statistics(to_normalised_planes(mosaic, *levels)))
        held += mosaic.size
        mosaics = mosaics + [mosaic] if mosaics is not None and held <= BURST_PIXELS else None
    if not blocks:
        return None, problems
    black, white = levels
    if mosaics and is_static_burst(mosaics):
        shot, read = _photon_transfer.fit_shot_read(*_photon_transfer.temporal_bins(mosaics, black, white))
        if fixed_read is not None:
            read = np.asarray(fixed_read, np.float64)
        if np.all(np.isfinite(shot)) and np.all(np.isfinite(read)):
            if methods is not None:
                methods.append(f"temporal ({len(mosaics)} frames of one static scene)")
            return (shot, read), problems
    if methods is not None:
        methods.append("flat blocks")
    estimate = _estimation.estimate_noise_level_function(blocks[0].concatenate(*blocks[1:]),
                                                         clip_low=-black / (white - black), n_bootstrap=n_bootstrap)
    shot, read = _extension.fit_shot_read(estimate, floor_variance=0.0)
    if fixed_read is not None:
        read = np.asarray(fixed_read, np.float64)
        shot = shot_with_read_held(estimate, read)
    if not (np.all(np.isfinite(shot)) and np.all(np.isfinite(read))):
        names = ", ".join(Path(i.path).name for i in infos)
        return None, problems + [(names, f"too few flat regions to measure the noise "
                                         f"(pooled over {len(blocks)} file(s))")]
    # rounding to DN is part of the measured variance and of every raw: keep it in `read`
    read = np.maximum(read, _estimation.quantisation_variance(black, white))
    return (shot, read), problems


def shot_with_read_held(estimate, read) -> np.ndarray:
    """(4,) shot term of variance = shot x + read with `read` (4,) given, fitted to a
    `NoiseLevelEstimate`'s bins by least squares on the relative residual (weights 1 / (variance x
    log SE), as `extension.fit_shot_read`), floored at 0; NaN where a position has no bin."""
    shot = np.full(4, np.nan)
    for p in range(4):
        ok = estimate.valid()[p] & (estimate.lower[p] > 0) & (estimate.signal[p] > 0)
        if not ok.any():
            continue
        x, v = estimate.signal[p, ok], estimate.variance[p, ok]
        se = np.maximum(np.log(estimate.upper[p, ok] / estimate.lower[p, ok]) / (2 * 1.96), 1e-3)
        w = 1.0 / (v * se) ** 2
        shot[p] = max(float(np.sum(w * x * (v - read[p])) / np.sum(w * x * x)), 0.0)
    return shot


def dark_frames_by_iso(dark_frames) -> dict:
    """{ISO: DarkFrameReadNoise} of [(info, DarkFrameStatistics)] (`dark_frames.find_dark_frames`),
    each ISO's frames pooled at the median levels of their tags."""
    from g2r_jax.sensor.dark_frames import read_from_dark_frames

    groups = {}
    for info, stats in dark_frames:
        groups.setdefault(float(info.iso) if info.iso else 100.0, []).append((info, stats))
    out = {}
    for iso, members in groups.items():
        black = np.median(np.stack([_levels(i)[0] for i, _ in members]), axis=0)
        white = float(np.median([_levels(i)[1] for i, _ in members]))
        out[iso] = read_from_dark_frames([s for _, s in members], black, white)
    return out


def noise_and_source(infos, cfa_pattern, dtype=np.float32, *, measure: bool = True, dark_frames=()):
    """(NoiseModel, source) for a profile fitted from `infos`; see the module docstring.

    `measure=False` skips the pixel measurement (tags only). `dark_frames`: [(info,
    DarkFrameStatistics)] of the folder's dark frames (not among `infos`), whose read term
    replaces that of their ISO. `source` is one sentence for the profile's provenance."""
    dark = dark_frames_by_iso(dark_frames)
    tag_rows, kinds, to_measure = _sort_by_noise_profile(infos, cfa_pattern)
    measured_rows, unmeasured, problems, methods = _measure_groups(to_measure, dark, measure)
    floored_rows = _floored_degenerate_rows(unmeasured, cfa_pattern)
    rows = {iso: tag_rows[iso] for iso in tag_rows}
    for iso, values in measured_rows.items():
        rows.setdefault(iso, values)
    for iso, values in floored_rows.items():
        rows.setdefault(iso, values)
    # the dark frames' read term for every row of their ISO (tags' shot kept; a measured shot was
    # fitted with it held); with no other file at all, dark frames alone give rows without shot noise
    used_dark = {iso: found for iso, found in dark.items() if iso in rows or not infos}
    for iso, found in used_dark.items():
        rows[iso] = ([np.stack([row[:, 0], found.read], axis=1) for row in rows[iso]] if iso in rows
                     else [np.stack([np.zeros(4), found.read], axis=1)])
    _warn_unusable_profiles(kinds, problems, bool(rows))
    if not rows:
        isos = np.asarray(sorted({float(i.iso) if i.iso else 100.0 for i in infos}))
        model = _sensor.NoiseModel(iso=jnp.asarray(isos, dtype), shot=jnp.zeros((len(isos), 4), dtype),
                                   read=jnp.zeros((len(isos), 4), dtype),
                                   iso_range=jnp.asarray([isos.min(), isos.max()], dtype))
        return model, "noise: NONE - no file has a usable NoiseProfile and none could be measured (no noise is simulated)"
    isos = np.array(sorted(rows))
    table = np.stack([np.median(np.stack(rows[i]), axis=0) for i in isos])
    model = _sensor.NoiseModel(iso=jnp.asarray(isos, dtype), shot=jnp.asarray(table[..., 0], dtype),
                               read=jnp.asarray(table[..., 1], dtype),
                               iso_range=jnp.asarray([isos.min(), isos.max()], dtype))
    n_measured = sum(len(v) for iso, v in measured_rows.items() if iso not in tag_rows)
    n_floored = sum(len(v) for iso, v in floored_rows.items() if iso not in tag_rows and iso not in measured_rows)
    parts = _source_parts(sum(len(v) for v in tag_rows.values()), n_measured, methods, n_floored, used_dark)
    _warn_dark_frames(dark, used_dark, bool(infos))
    return model, "noise: " + "; ".join(parts) + f" (ISO {', '.join(f'{i:g}' for i in isos)})"


def _sort_by_noise_profile(infos, cfa_pattern):
    """(tag rows by ISO, file names by `classify_noise_profile` kind, files to measure grouped by
    ISO and levels): files of one ISO and one black/white level pool their flat blocks."""
    tag_rows, kinds, to_measure = {}, {}, {}
    for info in infos:
        iso = float(info.iso) if info.iso else 100.0
        kind = classify_noise_profile(info)
        kinds.setdefault(kind, []).append(Path(info.path).name or "<unnamed>")
        if kind == "ok":
            tag_rows.setdefault(iso, []).append(_tag_per_position(info, cfa_pattern))
            continue
        to_measure.setdefault((iso, tuple(_levels(info)[0]), _levels(info)[1]), []).append(info)
    return tag_rows, kinds, to_measure


def _measure_groups(to_measure, dark, measure: bool):
    """(measured rows by ISO, files left unmeasured, (name, problem) pairs, methods used):
    `measure_pooled` on each group, the read term held at the dark frames' where they give one."""
    measured_rows, unmeasured, problems, methods = {}, [], [], []
    for (iso, _, _), group in to_measure.items():
        if not measure:
            problems.extend((Path(i.path).name, "pixels not measured") for i in group)
            unmeasured.extend(group)
            continue
        measured, failed = measure_pooled(group, fixed_read=dark[iso].read if iso in dark else None,
                                          methods=methods)
        problems.extend(failed)
        if measured is not None:
            # one row per file measured, so that the per-ISO median weighs files, not groups
            n_read = len(group) - sum(1 for name, _ in failed if name in {Path(i.path).name for i in group})
            measured_rows.setdefault(iso, []).extend([np.stack(measured, axis=1)] * max(n_read, 1))
        else:
            unmeasured.extend(group)
    return measured_rows, unmeasured, problems, methods


def _floored_degenerate_rows(unmeasured, cfa_pattern) -> dict:
    """Rows by ISO of the unmeasured files with a degenerate NoiseProfile: S at least 0, O at least
    the rounding variance 1/12 DN^2."""
    floored_rows = {}
    for info in unmeasured:
        if classify_noise_profile(info) == "degenerate":
            table = _tag_per_position(info, cfa_pattern)
            black, white = _levels(info)
            table[:, 0] = np.maximum(np.nan_to_num(table[:, 0]), 0.0)
            table[:, 1] = np.maximum(np.nan_to_num(table[:, 1]), _estimation.quantisation_variance(black, white))
            floored_rows.setdefault(float(info.iso) if info.iso else 100.0, []).append(table)
    return floored_rows


NAMES_SHOWN = 5   # file names a warning lists before it counts the rest


def _named(names) -> str:
    """'a.dng, b.dng, ...' for a few names; the first `NAMES_SHOWN` and a count for many (a folder
    of 300 DNGs must not make a warning of 300 names)."""
    names = [n for part in names for n in str(part).split(", ")]
    if len(names) <= NAMES_SHOWN:
        return ", ".join(names)
    return f"{', '.join(names[:NAMES_SHOWN])} and {len(names) - NAMES_SHOWN} more ({len(names)} files)"


def _warn_unusable_profiles(kinds, problems, any_rows: bool) -> None:
    bad = {k: v for k, v in kinds.items() if k != "ok"}
    if not bad:
        return
    listing = "; ".join(f"{kind}: {_named(names)}" for kind, names in sorted(bad.items()))
    by_reason = {}
    for name, reason in problems:
        by_reason.setdefault(reason, []).append(name)
    why = "; ".join(f"{_named(names)}: {reason}" for reason, names in by_reason.items())
    outcome = "noise measured from their pixels" if not problems else f"could not measure all of them ({why})"
    if not any_rows:
        outcome = f"no noise could be measured ({why}); the profile simulates NO NOISE"
    warnings.warn(f"no usable NoiseProfile ({listing}): {outcome}", stacklevel=3)


def _source_parts(n_tags: int, n_measured: int, methods, n_floored: int, used_dark) -> list[str]:
    """The provenance sentence's parts: where each row of the noise table came from."""
    parts = []
    if n_tags:
        parts.append(f"NoiseProfile tags of {n_tags} file(s)")
    if n_measured:
        parts.append(f"measured from the pixels of {n_measured} file(s) without a usable NoiseProfile "
                     f"(S x + O per CFA position; {', '.join(sorted(set(methods)))}: g2r_jax.sensor.noise."
                     f"{'temporal' if any(m.startswith('temporal') for m in methods) else 'estimation'})")
    if n_floored:
        parts.append(f"degenerate NoiseProfile of {n_floored} file(s) with O raised to 1/12 DN^2")
    if used_dark:
        n_dark = sum(found.n_frames for found in used_dark.values())
        parts.append(f"read term from {n_dark} dark frame(s) (ISO {', '.join(f'{i:g}' for i in sorted(used_dark))}; "
                     f"g2r_jax.measure.dark_frames: variance per CFA site, hot pixels left out)")
    return parts


def _warn_dark_frames(dark, used_dark, any_infos: bool) -> None:
    if used_dark and not any_infos:
        warnings.warn(f"only dark frames ({sum(f.n_frames for f in used_dark.values())}): their read noise is "
                      "used, but no file with light gives the shot noise; the profile simulates NO SHOT NOISE",
                      stacklevel=3)
    unused = sorted(set(dark) - set(used_dark))
    if unused:
        warnings.warn(f"dark frames at ISO {', '.join(f'{i:g}' for i in unused)} not used: no other file of that "
                      "ISO gives a shot term to go with their read noise", stacklevel=3)
