"""The few-DNG regime (issue 33): an illuminant estimator trained on g2r_jax RAW whose lights come from
0 (the profile as shipped), 1, 3, 5, 10, 25 or all of the camera's measured lights, per illuminant
model, tested on the camera's real NUS images (the protocol of `g2r_jax.downstream.illuminant.experiment`:
folds by `measure.folds_of`, training lights from the training folds only, tested on the held-out fold).

Rows: `shipped` (the profile as given, lights 0), and each model of `--models` at each count of
`--lights`: `prior` and `locus` use no light (lights 0 only); `kernel` needs one; `auto` is what
g2r-fit-profile fits; `pooled` is `illuminants.pooled` with the camera under test left out of the
pool (leave-one-camera-out: none of its lights informs its own prior); `upi` (lights 0, CG
content only) is UPI's random cameras on the same views, as `downstream.illuminant.experiment`'s upi row;
`pooled-gs` leaves all nine
NUS cameras out (only the Gehler-Shi lights: other scenes, since the NUS cameras shot many of the
same scenes, so `pooled` may know the test camera's scenes' lights from its siblings); `auto-gs`
is `auto` with all nine NUS cameras left out of its pool (`choose_illuminant_model(exclude=)`): the
product's default measured leave-one-dataset-out (below 10 lights the Gehler-Shi lights blended
with the camera's; from 10 the kernel with the cross-camera prior, which holds no NUS light, so
there `auto-gs` is `auto` and trains once); `near:H`, `wide:H` and `n0:K` are `--energy-lodo`'s
few-light variants (`_lodo_variant`) with all nine NUS cameras out of the pool. Each count below all is
drawn `--draws` times per fold (a different random subset of the fold's training files each).
Content: `cg` (the CARLA frames, the paper's setting), `cg-cast` (the same through the `cast`
content model, each frame's cast taken to the NUS prior's with the camera under test left out,
through its matrices: issue 32, for UPI too; the median cast of the shipped profile's model),
`cg-scenes` (the content model a user gets today: with 0 files the shipped profile's, the prior's
'scenes' table with the camera under test left out; from 1 file the `scenes` model `g2r-fit-profile` fits, fitted to the same
training files whose lights the row uses, each file white-balanced by its light as by its
AsShotNeutral, the prior of real scenes it shrinks toward with the camera under test left out as
in `cg-cast`; UPI at 0 on the same views) or `real` (the training
folds' real images relit to the model's lights, `experiment`'s real_profile_light: the lights'
own cost).
Identical models (e.g. `auto` below 10 lights and `prior`) are trained once.

    python benchmarks/few_lights.py [--cameras Canon600D,NikonD40] [--lights 0,1,5,all]
        [--models prior,locus,kernel,pooled] [--content cg,cg-cast,cg-scenes,real]
        [--estimators cnn,moments,histogram]
        [--seeds 1] [--n 300] [--draws 1] --out out/few_lights.jsonl
    python benchmarks/few_lights.py --summary --out out/few_lights.jsonl
    python benchmarks/few_lights.py --energy
    python benchmarks/few_lights.py --energy-lodo default,n0:20,near:12,wide:2 --lights 0,1,5

Every finished (camera, row, content, estimator, seed, fold, draw) is one line of `--out`, so a run
stopped early keeps what it did and a rerun with the same `--out` skips it; `--summary` prints
the table of a results file (mean over folds and draws per camera, then over cameras).
Profiles and data as in benchmarks/downstream_nus.py.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from downstream_nus import CAMERAS, CARLA, DATA, NUS, camera_profile, shipped_content_model  # noqa: E402

MODELS = ("prior", "locus", "kernel", "auto", "auto-gs", "pooled", "pooled-gs")
NO_LIGHT_MODELS = ("prior", "locus")
CONTENTS = ("cg", "cg-cast", "cg-scenes", "real")


_POOLED_BASES = {}


def model_for(name, camera, profile, lights):
    """The profile with the illuminant model `name` fitted to `lights` (N, 3) of this camera, or
    None where the model does not take that many lights. `pooled` leaves `camera` out of the pool,
    `pooled-gs` and `auto-gs` every NUS camera (`CAMERAS`)."""
    from g2r_jax.illuminants import choice
    from g2r_jax.illuminants.distributions import neutral_to_chromaticity
    from g2r_jax.profile.schema import replace

    points = neutral_to_chromaticity(np.asarray(lights, np.float64).reshape(-1, 3))
    if name in ("shipped", "upi"):    # upi: UPI's random cameras (`run_camera` makes its set)
        return profile if len(points) == 0 else None
    if (name in NO_LIGHT_MODELS and len(points)) or (name == "kernel" and not len(points)):
        return None
    if name.startswith("pooled"):
        from g2r_jax.illuminants.pooled import pooled_base

        exclude = (camera,) if name == "pooled" else CAMERAS
        if (camera, name) not in _POOLED_BASES:
            _POOLED_BASES[(camera, name)] = pooled_base(
                profile.colour, lambda p: choice.camera_locus_tangents(p, profile.colour), exclude=exclude)
        model, _ = choice.fit_pooled_for_camera(points, profile.colour, exclude=exclude,
                                                base=_POOLED_BASES[(camera, name)])
    elif name == "auto-gs":
        model = choice.choose_illuminant_model(points, profile.colour, "auto", exclude=CAMERAS).model
    elif _is_variant(name):    # the few-light variants of --energy-lodo, every NUS camera out of the pool
        model = _lodo_variant(name, points, profile.colour, CAMERAS)
    else:
        model = choice.choose_illuminant_model(points, profile.colour, name).model
    return replace(profile, illuminants=model)


def _is_variant(name: str) -> bool:
    """Whether `name` is one of `_lodo_variant`'s few-light variants ('n0:K', 'near:H', 'wide:H')."""
    kind, colon, value = name.partition(":")
    try:
        return bool(colon) and kind in ("n0", "near", "wide") and float(value) > 0
    except ValueError:
        return False


def fingerprint(profile) -> str:
    """Identity of an illuminant model: the hash of its arrays (identical models train once)."""
    digest = hashlib.sha1(profile.illuminants.kind.encode())
    for leaf in (profile.illuminants.weights, profile.illuminants.means, profile.illuminants.cholesky,
                 profile.illuminants.hull):
        digest.update(np.ascontiguousarray(np.asarray(leaf, np.float32)).tobytes())
    return digest.hexdigest()[:16]


def subset_indices(n_train, count, draws, seed, fold):
    """`draws` random subsets of `count` of the fold's `n_train` training files, as indices into
    them (all of them once for count None or count >= n_train)."""
    if count is None or count >= n_train:
        return [np.arange(n_train)]
    return [np.random.default_rng([seed, fold, count, draw]).choice(n_train, count, replace=False)
            for draw in range(draws)]


_PRIORS_WITHOUT = {}


def scenes_content(camera, profile, images, lights, views):
    """The content model of `cg-scenes` for the training files `images` (N, 64, 64, 3) with lights
    (N, 3): what `g2r-fit-profile` fits to N >= 1 DNGs (`downstream.content_rows.FITTED`, the
    'scenes' family, the files white-balanced by their lights as by their AsShotNeutral), its cast
    centre shrunk toward the prior of real scenes without `camera` (`content.prior.real_scenes_without`,
    as the shipped profiles' prior leaves their camera out); with no file, the content model a
    shipped profile carries (`shipped_content_model`: the prior's scenes)."""
    from g2r_jax.content import prior as content_prior
    from g2r_jax.downstream.base.product import FITTED, candidate_model

    if len(images) == 0:
        return shipped_content_model(camera, profile.colour)
    if camera not in _PRIORS_WITHOUT:
        _PRIORS_WITHOUT[camera] = content_prior.real_scenes_without(DATA, camera)
    from g2r_jax.content.prior import scene_covariance

    return candidate_model(FITTED, images, lights, views, profile, prior_medians=_PRIORS_WITHOUT[camera],
                           prior_covariance=scene_covariance(DATA, camera))


def _done(out: Path) -> set:
    if not out.exists():
        return set()
    keys = set()
    for line in out.read_text().splitlines():
        r = json.loads(line)
        keys.add((r["camera"], r["model"], r["lights"], r["content"], r["estimator"], r["seed"], r["fold"], r["draw"]))
    return keys


def scenes_views(camera, profile, images, lights, views, cg_views, salt):
    """The CG `views` through `scenes_content` of the files `images` with `lights` (the scenes
    drawn per view from `salt`); with no file the shipped profile's model (the prior's scenes)."""
    from g2r_jax.downstream.base.product import adapted_views

    return adapted_views(scenes_content(camera, profile, images, lights, views), views, salt)


def run_camera(camera, args, out, say):
    """Every row of one camera; one JSON line per finished result."""
    from PIL import Image

    from g2r_jax.downstream.base import real_sets, training_sets as sets
    from g2r_jax.downstream.illuminant.estimators import train_estimator
    from g2r_jax.measure import angular_error_degrees, folds_of

    done = _done(out)
    profile = camera_profile(camera)
    real = real_sets.load_nus(NUS / f"{camera}.npz")
    linear = sets.linear_images([np.asarray(Image.open(f).convert("RGB")) for f in sorted(CARLA.glob("*.png"))])
    folds = folds_of(len(real.images), 3, 0, groups=real.groups)
    for seed in range(args.seeds):
        views = sets.cg_views(linear, args.n, seed)
        cg_views = {"cg": views}
        if "cg-cast" in args.content:    # the CARLA views through the content model a shipped profile carries
            from g2r_jax import content as content_model

            shipped_cast = content_model.as_cast(shipped_content_model(camera, profile.colour))   # the prior's cast
            cg_views["cg-cast"] = np.asarray(content_model.apply(shipped_cast, views))
        for fold, test in enumerate(folds):
            train = np.setdiff1d(np.arange(len(real.images)), test)
            trained, relit = {}, []
            for count in args.lights:
                for draw, chosen in enumerate(subset_indices(len(train), count, args.draws, seed, fold)):
                    chosen = chosen[:0] if count == 0 else chosen
                    lights, content_views = real.illuminants[train][chosen], dict(cg_views)
                    # cg-scenes: the content model of the same files whose lights the row uses (made when needed)
                    files_id = hashlib.sha1(np.ascontiguousarray(chosen, np.int64).tobytes()).hexdigest()[:12]
                    for name in args.models:
                        fitted = model_for(name, camera, profile, lights)
                        if fitted is None:
                            continue
                        for content in args.content:
                            base = dict(camera=camera, model=name, lights="all" if count is None else count,
                                        content=content, seed=seed, fold=fold, draw=draw)
                            if all((camera, name, base["lights"], content, e, seed, fold, draw) in done
                                   for e in args.estimators):
                                continue
                            start = time.perf_counter()
                            salt = 1000 * seed + 10 * fold + 4
                            if content == "cg-scenes" and content not in content_views:
                                content_views[content] = scenes_views(
                                    camera, profile, real.images[train][chosen], lights, views, cg_views,
                                    1000 * seed + 10 * fold + 5)
                            if name == "upi" and content in content_views:    # as `downstream.illuminant.experiment`'s upi row
                                images, labels = sets.upi_set(sets.linear_to_srgb_views(content_views[content]),
                                                              seed + 1)
                            elif name == "upi":
                                continue
                            elif content in content_views:
                                images, labels = sets.g2r_set(content_views[content], fitted, salt)
                            else:
                                if not relit:   # the training folds' real images, once per fold
                                    views_real = sets.real_to_linear_srgb(real.images[train], real.illuminants[train],
                                                                          profile)
                                    relit.append(np.concatenate([views_real] * -(-args.n // len(views_real)))[:args.n])
                                images, labels = sets.g2r_set(relit[0], fitted, salt + 4)
                            content_id = f"{content}:{files_id}" if content == "cg-scenes" else content
                            for estimator in args.estimators:
                                key = ("upi" if name == "upi" else fingerprint(fitted), content_id, estimator)
                                if key not in trained:
                                    predict = train_estimator(estimator, images, labels, seed=1000 * seed + fold)
                                    trained[key] = angular_error_degrees(predict(real.images[test]),
                                                                         real.illuminants[test])
                                errors = trained[key]
                                record = {**base, "estimator": estimator, "mean": float(np.mean(errors)),
                                          "n_test": int(len(errors)), "model_id": key[0],
                                          "seconds": round(time.perf_counter() - start, 1)}
                                with out.open("a") as stream:
                                    stream.write(json.dumps(record) + "\n")
                            say(f"{camera} seed {seed} fold {fold} {name} lights {base['lights']} draw {draw} "
                                f"{content}: {time.perf_counter() - start:.0f} s")


def summary(path: Path) -> str:
    """Markdown table: mean error per (content, estimator, model, lights), per camera and the mean
    of the cameras (each camera's figure: the mean over its folds, draws and seeds)."""
    records = [json.loads(line) for line in path.read_text().splitlines()]
    cameras = sorted({r["camera"] for r in records})
    cells = {}
    for r in records:
        cells.setdefault((r["content"], r["estimator"], r["model"], str(r["lights"]), r["camera"]), []).append(r["mean"])
    out = ["| content | estimator | model | lights | " + " | ".join(cameras) + " | mean of cameras |",
           "|---|---|---|---|" + "---|" * (len(cameras) + 1)]
    order = {str(k): i for i, k in enumerate([0, 1, 3, 5, 10, 25, 75, "all"])}
    for content, estimator, model, lights in sorted({k[:4] for k in cells},
                                                    key=lambda k: (k[0], k[1], MODELS.index(k[2]) if k[2] in MODELS
                                                                   else -1, order.get(k[3], 99))):
        per = [np.mean(cells[(content, estimator, model, lights, c)]) if (content, estimator, model, lights, c) in cells
               else np.nan for c in cameras]
        mean = f"{np.mean(per):.2f}" if not np.any(np.isnan(per)) else "-"
        out.append(f"| {content} | {estimator} | {model} | {lights} | "
                   + " | ".join("-" if np.isnan(v) else f"{v:.2f}" for v in per) + f" | {mean} |")
    return "\n".join(out)


def curve(path: Path, content: str, estimator: str) -> str:
    """Markdown table: models as rows, light counts as columns, the mean of the cameras that have
    every cell of the table (each camera: the mean over its folds, draws and seeds)."""
    records = [json.loads(line) for line in path.read_text().splitlines()]
    records = [r for r in records if r["content"] == content and r["estimator"] == estimator]
    counts = [c for c in ("0", "1", "3", "5", "10", "25", "75", "all") if any(str(r["lights"]) == c for r in records)]
    variants = sorted({r["model"] for r in records if _is_variant(r["model"])})
    models = [m for m in ("shipped", "upi", *MODELS, *variants) if any(r["model"] == m for r in records)]
    cells = {}
    for r in records:
        cells.setdefault((r["model"], str(r["lights"]), r["camera"]), []).append(r["mean"])
    keys = {(m, c) for m, c, _ in cells}
    cameras = sorted(cam for cam in {k[2] for k in cells} if all((m, c, cam) in cells for m, c in keys))
    out = [f"| model ({content}, {estimator}; mean of {len(cameras)} cameras) | " + " | ".join(counts) + " |",
           "|---|" + "---|" * len(counts)]
    for m in models:
        values = [np.mean([np.mean(cells[(m, c, cam)]) for cam in cameras]) if (m, c) in keys else None
                  for c in counts]
        out.append(f"| {m} | " + " | ".join("" if v is None else f"{v:.2f}" for v in values) + " |")
    return "\n".join(out) + f"\n\ncameras: {', '.join(cameras)}"


def energy_table(cameras) -> str:
    """Markdown: energy distance (`distributions.energy_distance`, Szekely & Rizzo 2013) between 2000
    draws of each zero-light model and all of the camera's measured NUS lights; `pooled` leaves the
    camera out, `pooled-gs` all nine NUS cameras."""
    import jax

    from g2r_jax.illuminants import choice, distributions as il

    out = ["| camera | prior | locus | pooled | pooled-gs |", "|---|---|---|---|---|"]
    table = []
    for camera in cameras:
        profile = camera_profile(camera)
        lights = il.neutral_to_chromaticity(np.load(NUS / f"{camera}.npz")["illuminants"].astype(np.float64))
        models = [choice.choose_illuminant_model(np.zeros((0, 2)), profile.colour, k).model for k in ("prior", "locus")]
        models += [choice.fit_pooled_for_camera(np.zeros((0, 2)), profile.colour, exclude=e)[0]
                   for e in ((camera,), CAMERAS)]
        row = [il.energy_distance(il.neutral_to_chromaticity(np.asarray(
            il.sample_neutrals(jax.random.PRNGKey(0), m, 2000), np.float64)), lights) for m in models]
        table.append(row)
        out.append(f"| {camera} | " + " | ".join(f"{v:.4f}" for v in row) + " |")
    out.append("| mean | " + " | ".join(f"{v:.4f}" for v in np.mean(table, axis=0)) + " |")
    return "\n".join(out)


GEHLER_SHI = ("Canon EOS-1D", "Canon EOS 5D")


def _lodo_targets():
    """(name, colour model, (N, 2) lights, pool sources to leave out): the two Gehler-Shi cameras
    with the NUS pool (every Gehler-Shi camera left out) and the nine NUS cameras with the
    Gehler-Shi pool (every NUS camera left out)."""
    from g2r_jax.illuminants import distributions as il
    from g2r_jax.illuminants.prior_fit import measured_sets

    out = [(m.name, m.colour_model, il.neutral_to_chromaticity(m.neutrals), GEHLER_SHI)
           for m in measured_sets(DATA) if m.name in GEHLER_SHI]
    for camera in CAMERAS:
        lights = il.neutral_to_chromaticity(np.load(NUS / f"{camera}.npz")["illuminants"].astype(np.float64))
        out.append((camera, camera_profile(camera).colour, lights, CAMERAS))
    return out


def _lodo_variant(variant, points, colour, exclude):
    """A few-light model for `--energy-lodo`: 'default' (what g2r-fit-profile fits), 'n0:K' (the
    pooled blend with K pseudo-lights for the pool, the default 5), 'near:H' (the pool's lights
    weighted by a kernel H times the default bandwidths around the files' lights), 'wide:H' (the
    pool's kernels H times wider)."""
    from g2r_jax.illuminants import choice, kernel, pooled

    if variant == "default":
        return choice.choose_illuminant_model(points, colour, "auto", exclude=exclude).model
    kind, _, value = variant.partition(":")
    carried = pooled.carried_lights(colour, exclude)
    spots, weights, factor = carried.chromaticities, carried.weights, float(value)
    bandwidths = kernel.DEFAULT_BANDWIDTHS
    if kind == "near" and len(points):
        covariances = kernel.kernel_covariances(choice.camera_locus_tangents(points, colour),
                                                factor * bandwidths[0], factor * bandwidths[1])
        offsets = spots[:, None, :] - points[None, :, :]
        distance = np.einsum("ijk,jkl,ijl->ij", offsets, np.linalg.inv(covariances), offsets)
        weights = weights * np.exp(-0.5 * distance).mean(1)
    wide = (factor * bandwidths[0], factor * bandwidths[1]) if kind == "wide" else bandwidths
    base = kernel.fit_kernel(spots, choice.camera_locus_tangents(spots, colour), bandwidths=wide,
                             weights=weights / weights.sum(), dtype=np.float64)
    if not len(points):
        return base
    pseudo = factor if kind == "n0" else kernel.PRIOR_PSEUDO_LIGHTS
    return kernel.fit_kernel(points, choice.camera_locus_tangents(points, colour), prior=base, prior_lights=pseudo,
                             bandwidths=bandwidths)


def energy_lodo_table(variants, counts, draws: int = 10) -> str:
    """Markdown: the energy distance (`distributions.energy_distance`, 1000 draws) between each
    few-light model of `count` lights drawn at random from a camera's measured lights and all of
    them, mean of `draws` draws, leave-one-dataset-out (`_lodo_targets`); the mean over the
    Gehler-Shi cameras (where a constant would be chosen) and over the NUS cameras."""
    import jax

    from g2r_jax.illuminants import choice, distributions as il

    rows = {}
    for name, colour, lights, exclude in _lodo_targets():
        for count in counts:
            for variant in variants:
                distances = []
                for draw in range(draws):
                    chosen = np.random.default_rng([count, draw]).choice(len(lights), count, replace=False)
                    points = choice.distinct_lights(lights[chosen]) if count else np.zeros((0, 2))
                    model = _lodo_variant(variant, points, colour, exclude)
                    drawn = il.sample_neutrals(jax.random.PRNGKey(draw), model, 1000)
                    distances.append(il.energy_distance(il.neutral_to_chromaticity(np.asarray(drawn, np.float64)), lights))
                rows[(name, count, variant)] = float(np.mean(distances))
    out = ["| lights | variant | Gehler-Shi (NUS pool) | NUS (Gehler-Shi pool) |", "|---|---|---|---|"]
    for count in counts:
        for variant in variants:
            gs = np.mean([rows[(n, count, variant)] for n in GEHLER_SHI])
            nus = np.mean([rows[(n, count, variant)] for n in CAMERAS])
            out.append(f"| {count} | {variant} | {gs:.4f} | {nus:.4f} |")
    return "\n".join(out)


def where_lights_sit() -> str:
    """Markdown: each NUS camera's measured lights as its own colour matrices place them (median
    mired and Duv x 1000, `illuminants.pooled`'s data), against the median of the other cameras'
    medians (what the pooled lights, carried through the matrices, expect). The NUS cameras shot
    largely the same scenes, so a camera far from the others is one whose matrices put the same
    lights elsewhere: its pooled lights (and the prior) sit off its real ones, whatever the model."""
    from g2r_jax.illuminants.pooled import load_pooled

    pool = load_pooled()
    medians = {name: np.median(points, axis=0) for name, points in pool.items() if name in CAMERAS}
    out = ["| camera | own lights: mired / Duv x 1000 | other NUS cameras' | difference | share above 200 mired |",
           "|---|---|---|---|---|"]
    for name in sorted(medians):
        others = np.median([m for other, m in medians.items() if other != name], axis=0)
        own, d = medians[name], medians[name] - others
        out.append(f"| {name} | {own[0]:.0f} / {own[1]:+.1f} | {others[0]:.0f} / {others[1]:+.1f} | "
                   f"{d[0]:+.0f} / {d[1]:+.1f} | {np.mean(pool[name][:, 0] > 200):.2f} |")
    return "\n".join(out)


def unknown_names(args) -> str:
    """The first of `--content`, `--estimators`, `--models` that names something unknown, as one
    line ('' when all are known)."""
    from g2r_jax.downstream.illuminant.estimators import ESTIMATORS
    from g2r_jax.illuminants.choice import KINDS

    models = tuple(dict.fromkeys(("shipped", "upi", *MODELS, *KINDS)))
    for option, given, known in (("--content", args.content, CONTENTS), ("--estimators", args.estimators, ESTIMATORS),
                                 ("--models", args.models, models)):
        unknown = [v for v in given.split(",") if v not in known and not (option == "--models" and _is_variant(v))]
        if unknown:
            return f"unknown {option} {', '.join(unknown)}; known: {', '.join(known)}"
    return ""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", default=",".join(CAMERAS))
    parser.add_argument("--lights", default="0,1,3,5,10,25,all")
    parser.add_argument("--models", default="shipped," + ",".join(MODELS))
    parser.add_argument("--content", default="cg,real")
    parser.add_argument("--estimators", default="cnn,moments")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--n", type=int, default=300)
    parser.add_argument("--draws", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("out/few_lights.jsonl"))
    parser.add_argument("--summary", action="store_true", help="print the table of --out and stop")
    parser.add_argument("--energy-lodo", default="", metavar="VARIANTS",
                        help="print the energy distance of few-light variants (default, n0:K, near:H, wide:H) "
                        "to all lights, leave-one-dataset-out, at --lights (numbers), and stop")
    parser.add_argument("--energy", action="store_true", help="print the zero-light models' energy distance "
                        "to each camera's measured lights and stop")
    args = parser.parse_args(argv)
    problem = unknown_names(args)
    if problem:
        print(problem, file=sys.stderr)
        return 2
    if args.summary:
        print(summary(args.out))
        for content, estimator in sorted({(r["content"], r["estimator"]) for r in map(json.loads, args.out.read_text().splitlines())}):
            print("\n" + curve(args.out, content, estimator))
        return 0
    if not NUS.is_dir() or not CARLA.is_dir():
        print(f"cannot run: needs {NUS} and {CARLA}", file=sys.stderr)
        return 2
    if args.energy_lodo:
        print(energy_lodo_table(args.energy_lodo.split(","), [int(c) for c in args.lights.split(",")]))
        return 0
    if args.energy:
        print(energy_table(args.cameras.split(",")))
        print("\n" + where_lights_sit())
        return 0
    from g2r_jax.runtime import compile_cache

    compile_cache.enable(program="g2r_jax-downstream")
    args.lights = [None if v == "all" else int(v) for v in args.lights.split(",")]
    args.models, args.content = args.models.split(","), args.content.split(",")
    args.estimators = args.estimators.split(",")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    for camera in args.cameras.split(","):
        run_camera(camera, args, args.out, lambda m: print(m, file=sys.stderr, flush=True))
    print(summary(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
