"""Why desaturating the CG frames helps (issue 32, finding 3 of docs/pages/validation/content_model.md):
is it each pixel's chroma, or each frame's grey-world cast?

Variants of the CARLA views (linear sRGB), each made RAW by g2r_jax under lights fitted to the
inner two thirds of a NUS camera's training folds, an estimator trained on it and tested on the
inner third (`g2r_jax.downstream.illuminant.content_rows.inner_split`: the test fold is not read at all):
- `identity`; `chroma@S` (x' = Y + S (x - Y): the pixels' chroma *and* the frame's mean cast scaled
  by S); `cast@C` (only the frame's grey-world cast, by a gain per channel, toward neutral: family
  'cast'); `cast` (the family as fitted without labels to the inner two thirds' thumbnails: each
  frame's cast taken to their median cast);
- `chroma@S+cast`: chroma scaled by S, then each frame's mean colour put back (the pixels less
  colourful, the cast unchanged): the control that separates the two.

    python benchmarks/content_mechanism.py [--cameras Canon600D,NikonD40,SonyA57] [--seed 0] [--n 200]
        [--estimators moments,cnn] [--variants identity,chroma@0.35,cast@0.35,cast@0,chroma@0.35+cast,cast]
        [--seeds 1] [--files N] [--scenes-min-files K]

Issue 47's variants: `scenes` (the family, fitted per fold like `cast`); the prototypes it came
from, `draw` (each view's cast that of one inner file drawn at random), `cast+tone` (the median
cast and the median brightness, a luminance power) and `draw+tone` (one file's cast and brightness).

Issue 50's variants, the content of a profile without files: `prior-cast` (the shipped profile's before
issue 50's finding: the prior's median cast with the camera under test left out) and `prior-scenes` (`content.prior_scenes_model`:
a 'scenes' table drawn from the spread of the other eight cameras' scenes about their medians,
centred on the prior's medians without the camera); `scenes+prior@K` the files' scenes with K
of the prior's as pseudo-files (`fitting.scenes_model(prior_scenes=K)`).

Issue 49's: `V+texture`, variant V's views times a draw of the inner files' fine texture at the
thumbnails' 64 pixels across (`content.texture`; V must come before it in --variants).

Data: ../shared/data/estimation/nus/<camera>.npz and ../shared/data/cg/carla/*.png.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from downstream_nus import CARLA, NUS, camera_profile  # noqa: E402

VARIANTS = "identity,chroma@0.35,cast@0.35,cast@0,chroma@0.35+cast,chroma@0.1"


def variant_views(name: str, views: np.ndarray) -> np.ndarray:
    """The views (n, H, W, 3) through variant `name` (see the module docstring)."""
    from g2r_jax import content

    keep_cast = name.endswith("+cast")
    family, _, value = name.removesuffix("+cast").partition("@")
    if family == "identity":
        model = content.identity()
    elif family == "chroma":
        model = content.content_model(float(value), family="chroma")
    elif family == "cast" and not keep_cast:
        model = content.content_model(cast_scale=float(value), family="cast")
    else:
        raise ValueError(f"unknown variant {name!r}; expected identity, chroma@S, cast@C or chroma@S+cast")
    out = np.asarray(content.apply(model, views), np.float32)
    if keep_cast:
        means = views.mean(axis=(1, 2), keepdims=True)
        out = out * means / np.maximum(out.mean(axis=(1, 2), keepdims=True), 1e-12)
    return np.maximum(out, 0.0).astype(np.float32)


def _luminance_tone(views, targets):
    """Each view's luminance taken to the power p under its peak luminance, chroma kept
    (x' = x (Y / P)^(p - 1)), p found by bisection so that mean Y / max channel of the 64 x 64
    area average reaches `targets` (n,)."""
    from g2r_jax.content.scene_statistics import LUMINANCE, SIZE, _area_average

    small = _area_average(views.astype(np.float64), SIZE)
    def brightness(p):
        y = small @ LUMINANCE
        peak_y = np.maximum(y.max(axis=(1, 2), keepdims=True), 1e-12)
        out = small * (np.maximum(y, 1e-12) / peak_y)[..., None] ** (p[:, None, None, None] - 1)
        return (out @ LUMINANCE).mean(axis=(1, 2)) / np.maximum(out.max(axis=(1, 2, 3)), 1e-12)
    low, high = np.full(len(views), 0.25), np.full(len(views), 4.0)
    for _ in range(24):
        middle = 0.5 * (low + high)
        darker = brightness(middle) > targets    # brightness falls as p rises
        low, high = np.where(darker, middle, low), np.where(darker, high, middle)
    p = 0.5 * (low + high)
    y = views @ LUMINANCE.astype(np.float32)
    peak_y = np.maximum(y.max(axis=(1, 2), keepdims=True), 1e-12)
    return (views * (np.maximum(y, 1e-12) / peak_y)[..., None] ** (p[:, None, None, None] - 1)).astype(np.float32)


def _highlight_tone(views, targets, knee: float = 0.5):
    """Each view's luminance above `knee` of its peak raised to a power q >= 1 about the knee (the
    highlights spread upward, the body below the knee unchanged, chroma kept):
    Y' = Y (Y / K)^(q - 1) above K; q found by bisection so that mean Y / max channel of the 64 x 64
    area average reaches `targets` (n,) (an end, 1 or 8, when out of reach)."""
    from g2r_jax.content.scene_statistics import LUMINANCE, SIZE, _area_average

    def curve(images, q):
        y = images @ LUMINANCE
        k = knee * np.maximum(y.max(axis=(1, 2), keepdims=True), 1e-12)
        factor = np.where(y > k, (np.maximum(y, 1e-12) / k) ** (q[:, None, None] - 1), 1.0)
        return images * factor[..., None]

    small = _area_average(views.astype(np.float64), SIZE)
    def brightness(q):
        out = curve(small, q)
        return (out @ LUMINANCE).mean(axis=(1, 2)) / np.maximum(out.max(axis=(1, 2, 3)), 1e-12)
    low, high = np.full(len(views), 1.0), np.full(len(views), 8.0)
    for _ in range(24):
        middle = 0.5 * (low + high)
        darker = brightness(middle) > targets
        low, high = np.where(darker, middle, low), np.where(darker, high, middle)
    return curve(views.astype(np.float64), 0.5 * (low + high)).astype(np.float32)


def drawn_views(name, views, images, lights, profile, rng):
    """Prototype of a distribution content model: 'draw' each view's cast taken to the cast of one
    real file drawn at random; 'draw+tone' that file's brightness too (a luminance power, chroma
    kept); 'cast+tone' the median cast and the median brightness."""
    from g2r_jax import content
    from g2r_jax.content.scene_statistics import LUMINANCE

    stats = content.statistics(content.white_balanced_camera_rgb(images, lights))
    ok = np.isfinite(stats.values["cast_red"]) & np.isfinite(stats.values["cast_blue"]) & np.isfinite(stats.values["brightness"])
    red, blue, bright = (stats.values[k][ok] for k in ("cast_red", "cast_blue", "brightness"))
    neutral = np.median(lights / lights[:, 1:2], axis=0)
    to_camera = content.srgb_to_camera_matrices(neutral[None], profile.colour)[0]
    if name.startswith("draw"):
        pick = rng.integers(len(red), size=len(views))
        red, blue, bright = red[pick], blue[pick], bright[pick]
    else:
        red, blue, bright = (np.full(len(views), np.median(v)) for v in (red, blue, bright))
    in_camera = np.stack([np.exp(red), np.ones_like(red), np.exp(blue)], -1)
    target = np.maximum(np.linalg.solve(to_camera[None], in_camera[..., None])[..., 0], 1e-3)
    target = target / (target @ LUMINANCE)[:, None]
    mean = np.maximum(views.astype(np.float64).mean(axis=(1, 2)), 1e-12)
    gains = (mean @ LUMINANCE)[:, None] * target / mean
    out = (views * gains[:, None, None, :].astype(np.float32))
    if name.endswith("+tone"):
        out = _luminance_tone(out, bright)
    if name.endswith("+top"):
        out = _highlight_tone(out, bright)
    return np.maximum(out, 0.0).astype(np.float32)


def prior_scenes_model(camera, profile, seed: int):
    """The `prior-scenes` variant: `content.prior_scenes_model` (what a shipped profile carries)
    with the camera under test left out of the prior's medians and covariance; no file of the
    camera is read."""
    from downstream_nus import DATA

    from g2r_jax import content
    from g2r_jax.content import prior

    return content.prior_scenes_model(profile.colour, prior.real_scenes_without(DATA, camera),
                                      prior.scene_covariance(DATA, camera), f"prior without {camera}", seed)


def blended_scenes_model(camera, profile, images, lights, views, prior_scenes: int, seed: int):
    """`scenes+prior@K`: the 'scenes' model of the files `images` (as `scenes`) with K scenes of the
    prior (`fitting.scenes_model(prior_scenes=K)`), the camera under test left out of the prior's
    medians and spread."""
    from downstream_nus import DATA

    from g2r_jax import content
    from g2r_jax.content import prior
    from g2r_jax.content.fitting import scenes_model

    real = content.statistics(content.white_balanced_camera_rgb(images, lights), source="inner files")
    neutral = np.median(lights / lights[:, 1:2], axis=0)
    to_camera = content.srgb_to_camera_matrices(neutral[None], profile.colour)[0]
    return scenes_model(real, to_camera, prior_medians=prior.real_scenes_without(DATA, camera),
                        prior_scenes=prior_scenes, prior_covariance=prior.scene_covariance(DATA, camera), seed=seed)


def textured_views(views, thumbnails, seed: int):
    """`views` times a draw of the thumbnails' texture at their own 64 pixels across (`content.texture`)."""
    import jax

    from g2r_jax.content.texture import add_texture, fit_texture

    model = fit_texture(thumbnails, grid=thumbnails.shape[1])
    return np.asarray(add_texture(model, views, jax.random.PRNGKey(seed)))


def run(cameras, variants, estimators, seed: int, n: int, files: int | None = None) -> dict:
    """{estimator/variant: {camera: [mean inner-third error per fold, degrees]}}; `files`: the fitted
    families ('cast', 'scenes') see only that many of the inner two thirds' files, drawn at random
    (as a user with few DNGs; the lights still come from all of them)."""
    from PIL import Image

    from g2r_jax.downstream.base import product, real_sets, training_sets
    from g2r_jax.downstream.illuminant import content_rows
    from g2r_jax.downstream.illuminant.estimators import train_estimator
    from g2r_jax.measure import angular_error_degrees, folds_of

    linear = training_sets.linear_images([np.asarray(Image.open(f).convert("RGB")) for f in sorted(CARLA.glob("*.png"))])
    views = training_sets.cg_views(linear, n, seed)
    adapted = {name: variant_views(name, views) for name in variants
               if name not in ("cast", "scenes", "prior-cast", "prior-scenes") and not name.startswith("scenes+prior@")
               and not name.startswith(("draw", "cast+tone", "cast+top")) and not name.endswith("+texture")}
    errors, start = {}, time.perf_counter()
    for camera in cameras:
        real = real_sets.load_nus(NUS / f"{camera}.npz")
        profile = camera_profile(camera)
        groups = getattr(real, "groups", None)
        for fold, test in enumerate(folds_of(len(real.images), 3, 0, groups=groups)):
            train = np.setdiff1d(np.arange(len(real.images)), test)
            inner, validate = content_rows.inner_split(train, groups, seed, fold)
            fitted = product.fitted_illuminants(profile, real.illuminants[inner], "auto", seed)
            scenes_of = inner if files is None else np.random.default_rng(60_000 + 100 * seed + fold).choice(
                inner, size=min(files, len(inner)), replace=False)
            for fitted_family in {"cast", "scenes"} & set(variants):    # fitted to the inner two thirds, per fold
                model = product.candidate_model(fitted_family, real.images[scenes_of], real.illuminants[scenes_of],
                                                views, profile)
                adapted[fitted_family] = product.adapted_views(model, views, 50_000 + 100 * seed + fold)
            if "prior-cast" in variants:
                from downstream_nus import shipped_content_model

                from g2r_jax.content import as_cast

                adapted["prior-cast"] = product.adapted_views(as_cast(shipped_content_model(camera, profile.colour)),
                                                              views, 50_000 + 100 * seed + fold)
            for name in [v for v in variants if v.startswith("scenes+prior@")]:   # the files' scenes and K of the prior's
                adapted[name] = product.adapted_views(
                    blended_scenes_model(camera, profile, real.images[scenes_of], real.illuminants[scenes_of], views,
                                         int(name.partition("@")[2]), 70_000 + 100 * seed + fold),
                    views, 50_000 + 100 * seed + fold)
            if "prior-scenes" in variants:
                adapted["prior-scenes"] = product.adapted_views(
                    prior_scenes_model(camera, profile, 70_000 + 100 * seed + fold),
                    views, 50_000 + 100 * seed + fold)
            for name in variants:
                if name.startswith("draw") or name.startswith(("cast+tone", "cast+top")):
                    adapted[name] = drawn_views(name, views, real.images[inner], real.illuminants[inner], profile,
                                                np.random.default_rng(50_000 + 100 * seed + fold))
            for name in [v for v in variants if v.endswith("+texture")]:     # issue 49's texture, at the thumbnails' scale
                adapted[name] = textured_views(adapted[name.removesuffix("+texture")], real.images[scenes_of],
                                               60_000 + 100 * seed + fold)
            for name in variants:
                images, labels = training_sets.g2r_set(adapted[name], fitted, 7_000 + 1000 * seed + fold)
                for estimator in estimators:
                    predict = train_estimator(estimator, images, labels, seed=1000 * seed + fold)
                    error = float(np.mean(angular_error_degrees(predict(real.images[validate]),
                                                                real.illuminants[validate])))
                    errors.setdefault(f"{estimator}/{name}", {}).setdefault(camera, []).append(error)
            print(f"  {camera} fold {fold + 1}/3 ({time.perf_counter() - start:.0f} s)", file=sys.stderr, flush=True)
    return errors


def table(errors: dict, cameras, variants, estimators) -> str:
    out = ["| estimator | variant | " + " | ".join(cameras) + " | mean |", "|---|---|" + "---|" * (len(cameras) + 1)]
    for estimator in estimators:
        for name in variants:
            per_camera = [float(np.mean(errors[f"{estimator}/{name}"][c])) for c in cameras]
            out.append(f"| {estimator} | {name} | " + " | ".join(f"{e:.2f}" for e in per_camera)
                       + f" | {np.mean(per_camera):.2f} |")
    return "\n".join(out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", default="Canon600D,NikonD40,SonyA57")
    parser.add_argument("--variants", default=VARIANTS)
    parser.add_argument("--estimators", default="moments,cnn")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seeds", type=int, default=1, help="seeds from --seed on, pooled")
    parser.add_argument("--n", type=int, default=200)
    parser.add_argument("--files", type=int, help="fit 'cast' and 'scenes' to this many of the inner files")
    parser.add_argument("--scenes-min-files", type=int,
                        help="fit 'scenes' from this many files on (g2r_jax.content.scenes.MIN_FILES; below it, 'cast')")
    args = parser.parse_args(argv)
    if not NUS.is_dir() or not CARLA.is_dir():
        print(f"cannot run: needs {NUS} and {CARLA}", file=sys.stderr)
        return 2
    cameras, variants, estimators = (args.cameras.split(","), args.variants.split(","), args.estimators.split(","))
    if args.scenes_min_files is not None:
        from g2r_jax.content import scenes

        scenes.MIN_FILES = args.scenes_min_files
    errors = {}
    for seed in range(args.seed, args.seed + args.seeds):
        for key, per_camera in run(cameras, variants, estimators, seed, args.n, args.files).items():
            for camera, values in per_camera.items():
                errors.setdefault(key, {}).setdefault(camera, []).extend(values)
    print("mean inner-third error (degrees, mean of the 3 folds and the seeds; the test folds are not read)\n")
    print(table(errors, cameras, variants, estimators))
    return 0


if __name__ == "__main__":
    sys.exit(main())
