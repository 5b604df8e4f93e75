"""Real test sets: the NUS 8-camera thumbnails, or a folder of a user's DNGs.

A user's DNG gives one thumbnail (`thumbnails.camera_rgb_thumbnail` of its black-subtracted,
range-scaled CFA tiles) labelled with its AsShotNeutral: the camera's own white balance, not a
measured chart, so the check measures how well a network trained on synthetic RAW agrees with
the camera's AWB on the user's scenes.
"""

from __future__ import annotations

import collections
import dataclasses
from pathlib import Path

import numpy as np

from g2r_jax.downstream.base import thumbnails as _thumbnails

NUS_LABEL = "measured (the grey patches of a ColorChecker in each scene)"
DNG_LABEL = "AsShotNeutral (the camera's own white balance)"


@dataclasses.dataclass
class RealSet:
    """Real thumbnails of one camera with their illuminants.

    `images` (N, 64, 64, 3) linear camera RGB, saturated pixels 0, maximum 1 (`thumbnails`);
    `illuminants` (N, 3); `label`: where the illuminants come from (a measured chart, or each
    file's AsShotNeutral: the camera's own white balance); `groups` (N,) labels of files with
    the same pixels (`g2r_jax.measure.duplicate_groups`; None: all distinct)."""

    name: str
    images: np.ndarray
    illuminants: np.ndarray
    label: str = "measured"
    files: tuple = ()
    groups: np.ndarray | None = None   # (N,) labels: files with the same pixels share one (kept in one fold)


def load_nus(path) -> RealSet:
    """One camera of the NUS set as republished (see ../shared/data/PROVENANCE.md): an .npz with
    `images` (N, 64, 64, 3) linear raw RGB and `illuminants` (N, 3)."""
    path = Path(path)
    try:
        with np.load(path) as data:
            images = np.asarray(data["images"], np.float32)
            illuminants = np.asarray(data["illuminants"], np.float64)
            names = tuple(str(n) for n in data["names"]) if "names" in data else ()
    except (OSError, KeyError, ValueError) as error:
        raise ValueError(f"{path}: not a real set (.npz with images and illuminants): {error}") from None
    if images.ndim != 4 or images.shape[1:] != (64, 64, 3) or illuminants.shape != (len(images), 3):
        raise ValueError(f"{path}: images {images.shape} and illuminants {illuminants.shape} are not "
                         "(N, 64, 64, 3) and (N, 3)")
    if not np.all(np.isfinite(illuminants)) or np.any(illuminants <= 0):
        raise ValueError(f"{path}: illuminants must be finite and positive")
    return RealSet(name=path.stem, images=images, illuminants=illuminants / illuminants.sum(1, keepdims=True),
                   label=NUS_LABEL, files=names)


MIN_DISTINCT_LIGHTS = 3        # lights more than DISTINCT_LIGHT_DEGREES apart a colour check needs
DISTINCT_LIGHT_DEGREES = 1.0   # labels closer than this count as one light
MIN_LABEL_SPREAD_DEGREES = 1.0  # the mean error of always guessing the labels' mean light must reach this


def dng_thumbnail(path):
    """(thumbnail (64, 64, 3), as-shot neutral (3,), DngInfo, pixel hash) of one Bayer DNG;
    DngError naming the file when it cannot be used (no label, constant pixels, nothing lit)."""
    from g2r_jax.io.dng_info import DngError
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels, require_colour_tags
    from g2r_jax.measure import pixel_hash
    from g2r_jax.profile.fitting import as_shot_neutral

    info = require_colour_tags(read_dng_info(path))
    neutral = as_shot_neutral(info)
    if neutral is None or not np.all(np.isfinite(neutral)) or np.any(neutral <= 0):
        raise DngError(path, "no usable AsShotNeutral (or AsShotWhiteXY): the file has no white-balance label")
    mosaic = read_dng_pixels(path, info)
    if mosaic.size and mosaic.min() == mosaic.max():
        raise DngError(path, f"every pixel reads {mosaic.flat[0]}: no scene, nothing to estimate a light from")
    rgb = _thumbnails.mosaic_to_camera_rgb(mosaic, info.cfa_pattern, info.black_level, info.white_level)
    try:
        thumb = _thumbnails.camera_rgb_thumbnail(rgb)
    except ValueError as error:
        raise DngError(path, str(error)) from None
    if thumb.max() <= 0:
        raise DngError(path, "every pixel is clipped or black: nothing to estimate a light from")
    return thumb, neutral, info, pixel_hash(mosaic)


def dng_paths(paths) -> tuple[list[Path], list[str]]:
    """The *.dng files of `paths` (files or folders), each file once however often it is given
    (a folder named twice, a link); and the repeats left out, as paths."""
    files, seen, repeats = [], set(), []
    for item in paths:
        item = Path(item)
        found = sorted(p for p in item.iterdir() if p.suffix.lower() == ".dng") if item.is_dir() else [item]
        for path in found:
            key = path.resolve()
            if key in seen:
                repeats.append(str(path))
            else:
                seen.add(key)
                files.append(path)
    return files, repeats


def _keep_majority(kept: list, key, describe) -> tuple[list, list]:
    """Split `kept` into the files whose `key(item)` is the most common and the others, each
    named as (path, describe(its key, the common key))."""
    common = collections.Counter(key(k) for k in kept).most_common(1)[0][0]
    return ([k for k in kept if key(k) == common],
            [(str(k[0]), describe(key(k), common)) for k in kept if key(k) != common])


def load_dng_folder(paths, *, on_file=None) -> tuple[RealSet, list[tuple[str, str]]]:
    """Thumbnails and as-shot neutrals of a camera's DNGs (files or folders of *.dng).

    Files that cannot be used, files of another camera than the majority's, and files whose
    calibration illuminants differ from the majority's are skipped and returned as (path,
    reason); a file given twice is read once; files with the same pixels under other names
    share a `groups` label (kept in one fold). `on_file(path)` is called after each file.
    **Returns:** (RealSet, skipped).
    """
    from g2r_jax.io.dng_info import DngError
    from g2r_jax.measure import duplicate_groups

    files, _ = dng_paths(paths)
    kept, skipped = [], []
    for path in files:
        try:
            thumb, neutral, info, digest = dng_thumbnail(path)
            kept.append((path, thumb, neutral, info.unique_camera_model or f"{info.make} {info.model}".strip(),
                         tuple(sorted(info.calibration_illuminants)), digest))
        except DngError as error:
            skipped.append((str(path), error.problem))
        except (OSError, ValueError) as error:
            skipped.append((str(path), str(error)))
        if on_file:
            on_file(path)
    if not kept:
        return RealSet(name="", images=np.zeros((0, 64, 64, 3), np.float32), illuminants=np.zeros((0, 3)),
                       label=DNG_LABEL), skipped
    kept, other = _keep_majority(kept, lambda k: k[3], lambda a, b: f"camera {a!r}, not {b!r} like the other files")
    skipped += other
    kept, other = _keep_majority(kept, lambda k: k[4], lambda a, b: f"calibration illuminants {list(a)} differ "
                                                                     f"from the other files' {list(b)}")
    skipped += other
    neutrals = np.stack([k[2] for k in kept])
    return RealSet(name=kept[0][3], images=np.stack([k[1] for k in kept]),
                   illuminants=neutrals / neutrals.sum(1, keepdims=True), label=DNG_LABEL,
                   files=tuple(str(k[0]) for k in kept),
                   groups=duplicate_groups([np.frombuffer(k[5].encode(), np.uint8) for k in kept])), skipped


def duplicates(real: RealSet) -> list[list[str]]:
    """The files of `real` that hold the same pixels, one list per group of two or more."""
    if real.groups is None:
        return []
    groups = collections.defaultdict(list)
    for label, path in zip(real.groups, real.files or [str(i) for i in range(len(real.groups))]):
        groups[int(label)].append(path)
    return [g for g in groups.values() if len(g) > 1]


def distinct_lights(illuminants, degrees: float = DISTINCT_LIGHT_DEGREES) -> np.ndarray:
    """(k, 3) lights of `illuminants` (N, 3) more than `degrees` apart: each label joins the first
    kept light within `degrees` of it (angular error, `g2r_jax.measure.angular_error_degrees`)."""
    from g2r_jax.measure import angular_error_degrees

    kept = []
    for light in np.asarray(illuminants, np.float64):
        if not kept or angular_error_degrees(np.array(kept), np.tile(light, (len(kept), 1))).min() > degrees:
            kept.append(light)
    return np.array(kept).reshape(-1, 3)


def label_problem(real: RealSet) -> str | None:
    """Why `real`'s labels cannot teach an illuminant estimator anything (None when they can).

    A colour check needs labels that vary: with one light an estimator that ignores the image is
    perfect (the issue's 32 frames of one AsShotNeutral: 'real training' 0.19 deg). We ask for
    `MIN_DISTINCT_LIGHTS` lights more than `DISTINCT_LIGHT_DEGREES` apart (with two, every
    training set of a cross-validation can hold a single light, and a held-out light is then
    never seen), and that always guessing the labels' mean light errs at least
    `MIN_LABEL_SPREAD_DEGREES` on average (below that, no estimator can beat a constant by
    more than the check's resolution).
    """
    from g2r_jax.measure import angular_error_degrees

    lights = np.asarray(real.illuminants, np.float64)
    if not len(lights):
        return None
    count = len(distinct_lights(lights))
    mean = lights.mean(0)
    spread = float(angular_error_degrees(np.tile(mean, (len(lights), 1)), lights).mean())
    if count >= MIN_DISTINCT_LIGHTS and spread >= MIN_LABEL_SPREAD_DEGREES:
        return None
    return (f"the {len(lights)} files' {real.label.split(' (')[0]} labels hold {count} distinct light(s) "
            f"(labels within {DISTINCT_LIGHT_DEGREES:g} deg counted once), and always guessing their mean errs "
            f"{spread:.2f} deg; the colour check needs at least {MIN_DISTINCT_LIGHTS} distinct lights and "
            f"{MIN_LABEL_SPREAD_DEGREES:g} deg: nothing can be learned from these labels (give DNGs shot under "
            f"several lights, or use --burst alone)")
