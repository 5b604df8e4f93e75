"""Fitting the content model from statistics of real and CG images, without labels.

Each parameter takes the median of one per-image statistic (`scene_statistics`) of the CG images
to that of the real images, in the camera's white-balanced RGB:
- `chroma_scale` s from the median log-chroma spread, `tone_power` p (family 'chroma_tone') from
  the median brightness under the peak;
- with a sample of the CG images at hand, each by bisection on the statistic of the transformed
  sample (both statistics are monotone in their parameter); with medians only, by the
  small-chroma approximation s = real spread / CG spread (log(Y + s d) - log Y ~ s d / Y) and
  p = log(real brightness) / log(CG brightness) (a power p takes a brightness b to about b^p).
The 'cast' family takes each CG image's grey-world cast all the way (`model.CAST_KEPT`) to the
median cast of the real images (`cast_red`, `cast_blue`: the real scenes balanced by their
as-shot neutral are warm on the median, the CARLA frames blue), a colour in the camera's
white-balanced RGB carried to linear sRGB by the inverse of `to_camera` (finding 3 of
docs/pages/validation/content_model.md).
Without real images the real medians come from the prior of real scenes
(`prior.REAL_SCENES`); without CG statistics, from the reference CG set (`prior.REFERENCE_CG`).
"""

from __future__ import annotations

import dataclasses

import jax
import numpy as np

from g2r_jax.content import prior as _prior
from g2r_jax.content.model import CAST_KEPT, FAMILIES, ContentModel, apply, content_model, identity
from g2r_jax.content.scene_statistics import LUMINANCE as _LUMINANCE
from g2r_jax.content.scene_statistics import NAMES, SIZE, ContentStatistics, _area_average, statistics

_MEDIANS = ("chroma_spread", "brightness")
_BISECTION_STEPS = 24
_apply = jax.jit(apply)


def _medians(stats, fallback: dict, what: str, names=_MEDIANS) -> tuple[dict, str]:
    """The medians `names` of `stats` (a `ContentStatistics`, a dict of medians, or None for
    `fallback`, a prior) and where they came from."""
    if stats is None:
        return {k: fallback["medians"][k] for k in names}, fallback["source"]
    if isinstance(stats, ContentStatistics):
        if len(stats) == 0:
            raise ValueError(f"{stats.source or what}: no images to fit the content model to")
        return {k: stats.median(k) for k in names}, stats.source or what
    missing = [k for k in names if k not in stats]
    if missing:
        raise ValueError(f"{what} medians lack {', '.join(missing)}")
    return {k: float(stats[k]) for k in names}, what


def _transformed_median(sample, to_camera, name: str, scale: float, power: float) -> float:
    adapted = np.asarray(_apply(content_model(scale, power, family="chroma_tone"), sample), np.float64)
    return statistics(np.maximum(adapted @ to_camera.T, 0.0)).median(name)


def _bisect(increasing, target: float, low: float, high: float) -> float:
    """The x in [low, high] where the increasing function reaches `target` (an end if it never does)."""
    if increasing(high) <= target:
        return high
    if increasing(low) >= target:
        return low
    for _ in range(_BISECTION_STEPS):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if increasing(middle) < target else (low, middle)
    return 0.5 * (low + high)


def _parameters_from_sample(real: dict, sample, to_camera, family: str) -> tuple[float, float]:
    sample = _area_average(np.asarray(sample, np.float32), SIZE).astype(np.float32)
    to_camera = np.eye(3) if to_camera is None else np.asarray(to_camera, np.float64)
    scale = _bisect(lambda s: _transformed_median(sample, to_camera, "chroma_spread", s, 1.0),
                    real["chroma_spread"], 0.0, 1.0)
    if family != "chroma_tone":
        return scale, 1.0
    # brightness falls as the power rises: bisect on its negative
    power = _bisect(lambda p: -_transformed_median(sample, to_camera, "brightness", scale, p),
                    -real["brightness"], 0.25, 4.0)
    return scale, power


def _parameters_from_medians(real: dict, cg: dict, family: str) -> tuple[float, float]:
    scale = float(np.clip(real["chroma_spread"] / cg["chroma_spread"], 0.0, 1.0))
    if family != "chroma_tone":
        return scale, 1.0
    if not (real["brightness"] < 1 and cg["brightness"] < 1):
        raise ValueError("cannot fit the tone power: a median brightness is 1 (every pixel at the peak)")
    return scale, float(np.clip(np.log(real["brightness"]) / np.log(cg["brightness"]), 0.25, 4.0))


def fit_content_model(real_statistics=None, cg_statistics=None, *, family: str = "chroma", cg_sample=None,
                      to_camera=None, prior_medians: dict | None = None, prior_covariance=None) -> ContentModel:
    """The content model of `family` (`model.FAMILIES`) that takes the CG images' statistics to
    the real images'.

    **Arguments:** `real_statistics`: a `ContentStatistics` of the camera's real images in its
    white-balanced RGB (`real_images.white_balanced_camera_rgb`), a dict of medians, or None for
    the prior of real scenes; `cg_statistics`: the same for the CG images to convert, or None for
    the reference CG set; `cg_sample`: optionally CG images in linear sRGB (N, H, W, 3), H, W >=
    64 (then the parameters are found by bisection on the transformed sample, and
    `cg_statistics` is not used); `to_camera`: (3, 3) linear sRGB -> the camera's white-balanced
    RGB for `cg_sample` (`real_images.srgb_to_camera_matrices`; default: the identity);
    `prior_medians`: the prior of real scenes' medians to fall back on and shrink toward (default
    `prior.REAL_SCENES`; e.g. `prior.real_scenes_without(data, camera)` in a leave-one-out run);
    `prior_covariance`: 'scenes' only, the spread of the prior's scenes (default `prior.SCENE_SPREAD`;
    `prior.scene_covariance(data, camera)` in a leave-one-out run).
    **Returns:** a `ContentModel`, its `target` the real medians it was fitted to.
    """
    if family not in FAMILIES:
        raise ValueError(f"unknown content family {family!r}; expected one of {', '.join(FAMILIES)}")
    if family == "identity":
        return identity()
    if family == "cast":
        return _cast_model(real_statistics, to_camera, prior_medians=prior_medians)
    if family == "scenes":
        return scenes_model(real_statistics, to_camera, prior_medians=prior_medians, prior_covariance=prior_covariance)
    real, real_source = _medians(real_statistics, _real_prior(prior_medians), "real images")
    if cg_sample is not None:
        scale, power = _parameters_from_sample(real, cg_sample, to_camera, family)
        cg_source = f"a sample of {len(cg_sample)} CG images"
    else:
        cg, cg_source = _medians(cg_statistics, _prior.REFERENCE_CG, "CG images")
        for name, value in {**real, **{f"CG {k}": v for k, v in cg.items()}}.items():
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"cannot fit the content model: median {name} is {value!r}")
        scale, power = _parameters_from_medians(real, cg, family)
    return content_model(scale, power, family=family, source=f"{real_source} vs {cg_source}", target=real)


def _real_prior(prior_medians: dict | None) -> dict:
    """`prior.REAL_SCENES`, or the given medians in its shape."""
    if prior_medians is None:
        return _prior.REAL_SCENES
    return {"medians": prior_medians, "source": "the prior of real scenes given"}


def _toward_the_prior(real: dict, stats, prior_medians: dict | None = None) -> dict:
    """The files' median casts shrunk toward the prior's by how many files there are: the median
    of n files has variance about (pi / 2) s^2 / n (s the per-image spread), the prior misses a
    camera's median by about t (the cameras' spread, `prior.CAST_SPREAD`), so the precision-
    weighted mean gives the files weight n / (n + (pi / 2) s^2 / t^2): 1 file 0.7 % (red) and
    1.7 % (blue), 150 files 52 % and 72 %. One scene's cast is not the camera's."""
    prior = _real_prior(prior_medians)["medians"]
    out = {}
    for name, value in real.items():
        weight = files_weight(name, int(np.isfinite(stats.values[name]).sum()))
        out[name] = weight * value + (1.0 - weight) * prior[name]
    return out


def files_weight(name: str, n: int) -> float:
    """The weight of n files' median `name` ('cast_red' or 'cast_blue') against the prior's in the
    'cast' target (`_toward_the_prior`): n / (n + (pi / 2) s^2 / t^2)."""
    spread = _prior.CAST_SPREAD[name]
    return n / (n + 0.5 * np.pi * (spread["per_image"] / spread["between_cameras"]) ** 2)


def _cast_model(real_statistics, to_camera, what: str = "real images", prior_medians: dict | None = None) -> ContentModel:
    """'cast': the target colour is the real images' median grey-world cast (shrunk toward the
    prior's by their number, `_toward_the_prior`), exp(cast_red), 1, exp(cast_blue) in the
    camera's white-balanced RGB, taken to linear sRGB by to_camera^-1; `what` names a dict of
    medians in the model's source."""
    real, source = _medians(real_statistics, _real_prior(prior_medians), what, ("cast_red", "cast_blue"))
    if isinstance(real_statistics, ContentStatistics):
        real = _toward_the_prior(real, real_statistics, prior_medians)
    if not all(np.isfinite(v) for v in real.values()):
        raise ValueError(f"cannot fit the content model: a median cast of {source} is not finite")
    in_camera = np.exp([real["cast_red"], 0.0, real["cast_blue"]])
    to_camera = np.eye(3) if to_camera is None else np.asarray(to_camera, np.float64)
    target = np.linalg.solve(to_camera, in_camera)
    if not np.all(target > 0):
        raise ValueError(f"cannot fit the content model: the real images' median cast {in_camera.round(3).tolist()} "
                         "is outside the sRGB gamut at this light")
    return content_model(cast_scale=CAST_KEPT, cast_target=target, family="cast",
                         source=f"{source}: the CG frames' grey-world cast to the real scenes' median", target=real)


def prior_cast_model(colour_model, real_medians: dict | None = None, source: str = "") -> ContentModel:
    """The 'cast' model for a camera without files at hand (a shipped profile): the prior of real
    scenes' median cast (`prior.REAL_SCENES`, or `real_medians`, a dict with `cast_red` and
    `cast_blue` from `source`, e.g. `prior.real_scenes_without(data, camera)`), carried to linear
    sRGB through `colour_model` (`DngColourModel`) at D65 (CIE 15:2004 xy 0.3127, 0.3290)."""
    return _cast_model(real_medians, _d65_to_camera(colour_model), source or "given medians")


def _d65_to_camera(colour_model) -> np.ndarray:
    """Linear sRGB -> the camera's white-balanced RGB at D65 (CIE 15:2004 xy 0.3127, 0.3290)."""
    import jax.numpy as jnp

    from g2r_jax.colour.dng_model import xy_to_camera_neutral
    from g2r_jax.content.real_images import srgb_to_camera_matrices

    neutral = np.asarray(xy_to_camera_neutral(jnp.asarray([0.3127, 0.3290]), colour_model), np.float64)
    return srgb_to_camera_matrices(neutral[None], colour_model)[0]


def prior_scenes_model(colour_model, real_medians: dict | None = None, covariance=None, source: str = "",
                       seed: int = 0) -> ContentModel:
    """The 'scenes' model for a camera without files at hand (a shipped profile): a table of
    `scenes.TABLE_SIZE` scenes drawn from the prior of real scenes, (cast_red, cast_blue, log
    brightness) Gaussian about the prior's medians (`prior.REAL_SCENES`, or `real_medians`) with
    the covariance of one camera's scenes about its own medians (`prior.SCENE_SPREAD`, or
    `covariance`), carried to linear sRGB through `colour_model` at D65 as `prior_cast_model` is;
    the table's medians are the prior's, so its median cast (`as_cast`) is `prior_cast_model`'s.
    Measured against `prior_cast_model` on the NUS cameras with the camera under test left out of
    both priors: docs/pages/validation/content_model.md, finding 5."""
    from g2r_jax.content.scenes import TABLE_SIZE

    medians = dict(_prior.REAL_SCENES["medians"] if real_medians is None else real_medians)
    drawn = prior_scene_draws(TABLE_SIZE, medians, covariance, seed)
    values = {name: np.full(TABLE_SIZE, float(medians.get(name, np.nan))) for name in NAMES}
    values.update(cast_red=drawn[:, 0], cast_blue=drawn[:, 1], brightness=drawn[:, 2])
    to_camera = _d65_to_camera(colour_model)
    drawn_scenes = ContentStatistics(values=values, source=source or "the prior of real scenes")
    model = scenes_model(drawn_scenes, to_camera, "the prior of real scenes", prior_medians=medians, prior_scenes=0)
    return dataclasses.replace(model, target=tuple(sorted({**dict(model.target), "prior_draws": 1.0}.items())))


def scene_cast_targets(real_statistics, to_camera, what: str = "real images", prior_medians: dict | None = None):
    """Each usable file's own scene for 'scenes': (the 'cast' model of the files, indices of the
    files with a finite cast and brightness (M,), their casts in linear sRGB (M, 3) re-centred on
    the cast model's target (NaN where one has no positive luminance at this light), their brightness (M,), the positions among those M of the distinct
    scenes (`scenes.distinct_scenes`)); None in place of the four arrays when `real_statistics`
    is not per-file statistics (medians)."""
    from g2r_jax.content.scenes import distinct_scenes

    cast = _cast_model(real_statistics, to_camera, what, prior_medians)
    if not isinstance(real_statistics, ContentStatistics):
        return cast, None, None, None, None
    values = real_statistics.values
    usable = np.isfinite(values["cast_red"]) & np.isfinite(values["cast_blue"]) & (values["brightness"] > 0)
    red, blue, brightness = (np.asarray(values[k], np.float64)[usable] for k in ("cast_red", "cast_blue", "brightness"))
    distinct = distinct_scenes(red, blue, brightness)
    if len(distinct) == 0:
        return cast, np.flatnonzero(usable), np.zeros((0, 3)), brightness, distinct
    centre = dict(cast.target)
    red = red - np.median(red[distinct]) + centre["cast_red"]
    blue = blue - np.median(blue[distinct]) + centre["cast_blue"]
    return cast, np.flatnonzero(usable), _linear_targets(red, blue, to_camera), brightness, distinct


def _linear_targets(red, blue, to_camera) -> np.ndarray:
    """Casts (log r/g, log b/g in the camera's white-balanced RGB) as linear sRGB colours (M, 3)
    through to_camera^-1, floored at 1e-3 of their luminance (NaN where it is not positive)."""
    in_camera = np.stack([np.exp(red), np.ones(len(red)), np.exp(blue)], -1)
    to_camera = np.eye(3) if to_camera is None else np.asarray(to_camera, np.float64)
    targets = np.linalg.solve(to_camera, in_camera.T).T
    luminance = targets @ _LUMINANCE
    return np.where(luminance[:, None] > 0, np.maximum(targets, 1e-3 * luminance[:, None]), np.nan)


def prior_scene_draws(count: int, medians: dict, covariance=None, seed: int = 0) -> np.ndarray:
    """`count` scenes (count, 3) of (cast_red, cast_blue, brightness) drawn from the prior of real
    scenes: (cast_red, cast_blue, log brightness) Gaussian about `medians` with `covariance`
    (`prior.SCENE_SPREAD`'s by default), the draws' medians moved onto `medians` exactly."""
    covariance = np.asarray(_prior.SCENE_SPREAD["covariance"] if covariance is None else covariance, np.float64)
    centre = np.array([medians["cast_red"], medians["cast_blue"], np.log(medians["brightness"])])
    drawn = np.random.default_rng(seed).multivariate_normal(centre, covariance, count)
    drawn += centre - np.median(drawn, axis=0)
    return np.stack([drawn[:, 0], drawn[:, 1], np.clip(np.exp(drawn[:, 2]), 1e-3, 1.0)], -1)


def scenes_model(real_statistics, to_camera, what: str = "real images", prior_medians: dict | None = None,
                 prior_scenes: int | None = None, prior_covariance=None, seed: int = 0) -> ContentModel:
    """'scenes' (`g2r_jax.content.scenes`): a table of the files' own scenes, each its grey-world
    cast and its brightness, the casts re-centred on the median shrunk toward the prior's
    (`_toward_the_prior`), carried to linear sRGB like 'cast' (a target outside the sRGB gamut at
    this light is floored at 1e-3 of its luminance), each distinct scene once
    (`scenes.distinct_scenes`), with `prior_scenes` (default `scenes.PRIOR_SCENES`) scenes of the
    prior of real scenes (`prior_scene_draws` with `prior_covariance`, seeded by `seed`, about the
    same cast centre and the prior's brightness) as pseudo-files: few files are not the camera's
    whole distribution of scenes, as few lights are not its lights. The 'cast' model when fewer
    than `scenes.MIN_FILES` scenes have a finite cast and brightness, or when `real_statistics` is
    not per-file statistics (medians)."""
    from g2r_jax.content.scenes import MIN_FILES, PRIOR_SCENES, table_rows

    prior_scenes = PRIOR_SCENES if prior_scenes is None else int(prior_scenes)
    cast, _, casts, brightness, distinct = scene_cast_targets(real_statistics, to_camera, what, prior_medians)
    if casts is None or len(distinct) < MIN_FILES:
        return cast
    centre = dict(cast.target)
    casts, brightness = casts[distinct], brightness[distinct]
    if prior_scenes > 0:    # the prior's scenes as pseudo-files (a Dirichlet process's n0), about the same centre
        medians = {**_real_prior(prior_medians)["medians"], "cast_red": centre["cast_red"], "cast_blue": centre["cast_blue"]}
        drawn = prior_scene_draws(prior_scenes, medians, prior_covariance, seed)
        casts = np.concatenate([casts, _linear_targets(drawn[:, 0], drawn[:, 1], to_camera)])
        brightness = np.concatenate([brightness, drawn[:, 2]])
    rows = table_rows(len(casts))
    targets = casts[rows]
    if not np.all(np.isfinite(targets)):
        raise ValueError("cannot fit the scenes model: a real scene's cast has no positive luminance at this light")
    source = real_statistics.source or what
    files = len(distinct)
    words = f"{files} distinct scenes" + (f" and {prior_scenes} of the prior of real scenes" if prior_scenes > 0 else "")
    extra = {"prior_scenes": float(prior_scenes)} if prior_scenes > 0 else {}
    return content_model(family="scenes", scene_casts=targets, scene_brightness=np.clip(brightness[rows], 1e-3, 1.0),
                         cast_target=np.asarray(cast.cast_target),
                         source=f"{source}: each CG frame's cast and brightness those of one of its {words}",
                         target={**centre, "brightness": float(np.median(brightness[:files])), "scenes": float(files),
                                 **extra})
