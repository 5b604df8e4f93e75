"""The paper's illuminant-estimation experiment on real images (Graphics2RAW, Seo et al. ICCV 2023,
Table 2 and supplement Tables S1, S4, S6), with controls that split the gap to real training.

Protocol: the real set's images are split into `folds` folds (`g2r_jax.measure.folds_of`: a
seeded permutation, image j in fold j mod k; files with the same pixels, `RealSet.groups`, in one
fold); for each fold, every row makes a training set, one estimator per row is trained on
it and tested on the fold's real images (angular error, degrees). Synthetic rows make `n`
training images from CG views; real controls repeat the training images up to `n`.

Rows (`ROWS`):
- upi: UPI (Brooks et al. CVPR 2019) on the CG views: random camera matrix and gains;
- published: the published recipe (`recipe='published'`), lights fitted to the training files;
- shipped: g2r_jax with the profile as given (no light of this camera's scenes);
- fitted: the product, g2r_jax as `g2r-fit-profile` makes it from the training files: the
  illuminant model fitted to their lights (their as-shot neutrals) and the content model (the
  profile's own when it carries one, else the 'cast' model fitted to the training files' scenes
  only, never the test fold: `downstream.illuminant.content_rows`);
- fitted_no_content: control: 'fitted' without a content model (what the content model gains);
- single: g2r_jax as `g2r-fit-profile` makes it from one training file (its light, its scene);
- real: the real training files;
- real_own_light: control: the training files rendered to sRGB at their measured white and
  made RAW again under that light (what the round trip costs by itself);
- real_other_light: the same, each relit to the measured light of a random other training file
  (what relighting through the DNG matrices costs);
- real_profile_light: the same, relit to lights drawn from the fitted model (what the
  illuminant model costs);
- other_content: real images of other scenes (another camera's, rendered to sRGB at their
  white) made RAW for this camera with the fitted model (content that is real but not this set's);
- upi_content: UPI on the adapted views of 'fitted' (the lead over UPI on equal content);
- real_plus_fitted, real_plus_upi: augmentation: the real training files together with the
  'fitted' (or 'upi') set, the recipe (real alone, mixed, pretrained) chosen on the training files
  only (`downstream.illuminant.augmentation`).
With `labelled`, 'real' and the augmented rows see only that many of the training files (the
others' lights still fit the synthetic rows' illuminant model, as `g2r-fit-profile` reads a folder).
The content's share of the gap is fitted - real_profile_light; the profile's is
real_profile_light - real; the content model's gain is fitted_no_content - fitted.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Optional

import numpy as np

from g2r_jax.downstream.base import training_sets as _sets
from g2r_jax.downstream.base.once import Once
from g2r_jax.downstream.base.product import fitted_illuminants
from g2r_jax.downstream.base.progress import advance
from g2r_jax.downstream.base.real_sets import RealSet
from g2r_jax.measure import angular_error_degrees, error_summary, folds_of
from g2r_jax.pipeline import without_content

ROWS = {
    "upi": "UPI (Brooks et al. 2019)",
    "published": "published recipe, lights fitted",
    "shipped": "g2r_jax, profile as given",
    "fitted": "g2r_jax as g2r-fit-profile makes it (lights, content model)",
    "fitted_no_content": "control: g2r_jax, lights fitted, no content model",
    "single": "g2r_jax, one DNG",
    "real": "real training files",
    "real_own_light": "control: real, own light",
    "real_other_light": "control: real, another's light",
    "real_profile_light": "control: real, lights from the model",
    "other_content": "control: other real scenes",
    "upi_content": "UPI on the same adapted content",
    "real_plus_fitted": "real files + g2r_jax (recipe chosen on the training files)",
    "real_plus_upi": "real files + UPI (recipe chosen on the training files)",
}
AUGMENTED_ROWS = {"real_plus_fitted": "fitted", "real_plus_upi": "upi"}   # row -> its synthetic set
EXTRA_ROWS: dict = {}   # rows added by `register_row`: name -> builder
SYNTHETIC_CG_ROWS = ("upi", "published", "shipped", "fitted", "fitted_no_content", "single")
CONTROL_ROWS = ("fitted_no_content", "real_own_light", "real_other_light", "real_profile_light", "other_content")
CONTENT_ROWS = ("upi_content",)   # not default: one more training set per fold and seed (`content_rows`)
# 'published' (the paper's code) and 'other_content' (needs another camera's set) are the
# benchmark's rows: a user's check trains the rows that answer their question.
# Rows trained side by side: one training keeps about one core busy (user time = wall time of
# g2r-downstream on 200 small DNGs, 2 cores); docs/pages/validation/performance.md has the figures.
MAX_WORKERS = 4
DEFAULT_ROWS = tuple(r for r in ROWS if r not in ("published", "other_content", "real_plus_upi")
                     and r not in CONTENT_ROWS)


@dataclasses.dataclass
class ExperimentResult:
    """Errors per (row, estimator): one array of per-image errors (all folds) per seed."""

    camera: str
    rows: tuple
    estimators: tuple
    seeds: tuple
    errors: dict
    seconds: float = 0.0
    notes: list = dataclasses.field(default_factory=list)
    recipes: dict = dataclasses.field(default_factory=dict)   # (augmented row, estimator) -> recipe per fold
    # (augmented row, estimator) -> per fold, {recipe: its cross-validated mean error on the training files}
    choice_scores: dict = dataclasses.field(default_factory=dict)
    labelled: Optional[int] = None
    files: int = 0                 # real images in the experiment (folds included)

    def summary(self, row: str, estimator: str) -> dict:
        """Error statistics pooled over seeds, plus the spread of the seeds' means."""
        per_seed = self.errors[(row, estimator)]
        pooled = error_summary(np.concatenate(per_seed))
        means = [float(np.mean(e)) for e in per_seed]
        return {**pooled, "seed_means": means, "seed_min": min(means), "seed_max": max(means)}

    def to_dict(self) -> dict:
        return {"camera": self.camera, "rows": list(self.rows), "estimators": list(self.estimators),
                "seeds": list(self.seeds), "seconds": self.seconds, "notes": self.notes,
                "labelled": self.labelled, "files": self.files, "recipes": {f"{r}/{e}": v for (r, e), v in self.recipes.items()},
                "choice_scores": {f"{r}/{e}": v for (r, e), v in self.choice_scores.items()},
                "summary": {f"{r}/{e}": self.summary(r, e) for r in self.rows for e in self.estimators}}


def register_row(name: str, label: str, builder) -> None:
    """Add a training-set row to the experiment (e.g. g2r_jax with and without a content model).

    **Arguments:** `name` (new, not in `ROWS`); `label` for the tables; `builder(sets, train,
    fold, seed)` -> (thumbnails (N, 64, 64, 3), illuminants (N, 3)), where `sets` is the
    experiment's `_Sets` (`views(seed)`, `fitted(train, fold, seed)`, `profile`, `real`, `n`).
    The row is then trained and reported like the others when named in `rows`.
    """
    if name in ROWS:
        raise ValueError(f"row {name!r} exists already")
    ROWS[name] = label
    EXTRA_ROWS[name] = builder


def _repeat_to(n: int, *arrays):
    count = len(arrays[0])
    reps = max(1, -(-n // count))
    return [np.concatenate([a] * reps)[: max(n, count)] for a in arrays]


class _Sets:
    """Builds and caches each row's training set for one camera, fold and seed."""

    def __init__(self, real: RealSet, profile, cg_linear, *, n, illuminant_model, other, single_light, lights,
                 labelled=None):
        self.real, self.profile, self.n, self.lights, self.labelled = real, profile, n, lights, labelled
        self.cg_linear, self.illuminant_model, self.other = cg_linear, illuminant_model, other
        self.single_light = single_light
        self.cache = {}
        self.fold_work = Once()   # the current fold's sets and trainings that rows share (new in `prepare`)
        self.notes = []   # lines for the result's notes (e.g. the content model each fold kept)

    def views(self, seed):
        key = ("views", seed)
        if key not in self.cache:
            self.cache[key] = _sets.cg_views(self.cg_linear, self.n, seed)
        return self.cache[key]

    def srgb_views(self, seed):
        key = ("srgb", seed)
        if key not in self.cache:
            self.cache[key] = _sets.linear_to_srgb_views(self.views(seed))
        return self.cache[key]

    def fitted(self, train: np.ndarray, fold: int, seed: int):
        """The profile with its illuminant model fitted to the training files' lights (cached)."""
        key = ("fitted", fold, seed)
        if key not in self.cache:
            lights = self.real.illuminants[train]
            if self.lights is not None and self.lights < len(lights):
                pick = np.random.default_rng(1000 * seed + 10 * fold + 9).choice(len(lights), self.lights, replace=False)
                lights = lights[pick]
            self.cache[key] = fitted_illuminants(self.profile, lights, self.illuminant_model, seed)
        return self.cache[key]

    def labelled_files(self, train: np.ndarray, fold: int, seed: int) -> np.ndarray:
        """The training files 'real' and the augmented rows see: all, or `labelled` of them drawn
        at random (seeded by fold and seed; the same for every such row)."""
        if self.labelled is None or self.labelled >= len(train):
            return train
        pick = np.random.default_rng(1000 * seed + 10 * fold + 11).choice(len(train), self.labelled, replace=False)
        return np.sort(train[pick])

    def fitted_to(self, lights: np.ndarray, seed: int):
        """The profile with its illuminant model fitted to `lights` (N, 3), this experiment's kind."""
        return fitted_illuminants(self.profile, lights, self.illuminant_model, seed)

    def prepare(self, rows, train: np.ndarray, fold: int, seed: int) -> None:
        """Make what several rows share (views, fitted lights, the fold's adapted content) before
        the rows are built side by side, so that no two threads make the same thing."""
        from g2r_jax.downstream.illuminant import content_rows

        rows = set(rows) | {AUGMENTED_ROWS[r] for r in rows if r in AUGMENTED_ROWS}
        self.fold_work = Once()
        if rows & set(SYNTHETIC_CG_ROWS + CONTENT_ROWS):
            self.views(seed)
        if set(rows) & {"fitted", "fitted_no_content", "published", "real_profile_light", "other_content"}:
            self.fitted(train, fold, seed)
        if "fitted" in rows or "upi_content" in rows:
            content_rows.prepare(self, train, fold, seed)
        if "upi" in rows or "upi_content" in rows:
            self.srgb_views(seed)

    def build(self, row: str, train: np.ndarray, fold: int, seed: int):
        from g2r_jax.downstream.illuminant import content_rows

        real = self.real
        salt = 1000 * seed + 10 * fold
        if row == "real" or row in AUGMENTED_ROWS:
            from g2r_jax.downstream.illuminant.augmentation import AugmentedSet

            labelled = self.labelled_files(train, fold, seed)
            files = (real.images[labelled], real.illuminants[labelled])
            if row == "real":
                return files
            synthetic = AUGMENTED_ROWS[row]
            return AugmentedSet(real=files, synthetic=self.fold_work.get(
                ("set", synthetic), lambda: self.build(synthetic, train, fold, seed)))
        if row == "upi":
            key = ("upi", seed)
            if key not in self.cache:
                self.cache[key] = _sets.upi_set(self.srgb_views(seed), seed + 1)
            return self.cache[key]
        if row == "shipped":
            key = ("shipped", seed)
            if key not in self.cache:
                self.cache[key] = _sets.g2r_set(self.views(seed), self.profile, seed + 2)
            return self.cache[key]
        if row in content_rows.BUILDERS:
            return content_rows.BUILDERS[row](self, train, fold, seed)
        if row in EXTRA_ROWS:
            return EXTRA_ROWS[row](self, train, fold, seed)
        lights = real.illuminants[train]
        if row == "single":
            pick = train[np.random.default_rng(salt + 3).integers(len(train))]
            one = fitted_illuminants(self.profile, real.illuminants[pick:pick + 1], self.single_light)
            return content_rows.one_file_row(self, one, pick, salt + 3, seed)
        fitted = self.fitted(train, fold, seed)
        if row in ("fitted_no_content", "published"):
            profile = without_content(fitted) if row == "fitted_no_content" else fitted
            return _sets.g2r_set(self.views(seed), profile, salt + 4, recipe="published" if row == "published" else "dng")
        fitted_real = without_content(fitted)   # the controls' content is real: no CG content model on it
        if row == "other_content":
            if self.other is None:
                raise ValueError("row other_content needs another real set and its profile (other=...)")
            key = ("other_views",)
            if key not in self.cache:
                other_set, other_profile = self.other
                self.cache[key] = _sets.real_to_linear_srgb(other_set.images, other_set.illuminants, other_profile)
            views, = _repeat_to(self.n, self.cache[key])
            return _sets.g2r_set(views, fitted_real, salt + 5)
        views = _sets.real_to_linear_srgb(real.images[train], lights, self.profile)
        views, own = _repeat_to(self.n, views, lights)
        if row == "real_own_light":
            return _sets.g2r_set(views, without_content(self.profile), salt + 6, neutrals=own)
        if row == "real_other_light":
            other = own[np.random.default_rng(salt + 7).permutation(len(own))]
            return _sets.g2r_set(views, without_content(self.profile), salt + 7, neutrals=other)
        if row == "real_profile_light":
            return _sets.g2r_set(views, fitted_real, salt + 8)
        raise ValueError(f"unknown row {row!r}; expected one of {', '.join(ROWS)}")


def trainings(rows, estimators, seeds, folds: int) -> int:
    """How many estimators `illuminant_experiment` trains (its units of progress)."""
    return len(rows) * len(estimators) * len(seeds) * folds


def illuminant_experiment(real: RealSet, profile, cg_images, *, rows=DEFAULT_ROWS, estimators=("cnn", "histogram"),
                          seeds=(0, 1, 2), n: int = 1000, folds: int = 3, illuminant_model: str = "auto",
                          single_light: str = "auto", lights: Optional[int] = None, other: Optional[tuple] = None,
                          progress: Optional[Callable[[str], None]] = None,
                          workers: Optional[int] = None, labelled: Optional[int] = None,
                          cache=None) -> ExperimentResult:
    """Train illuminant estimators on each row's training set, test them on the real images.

    **Arguments:** `real`: the real set (`RealSet`); `profile`: the camera's `SensorProfile` (its
    colour model and sensor; its illuminant model is the 'shipped' row's); `cg_images`: CG
    images, sRGB-coded uint8 (H, W, 3) or linear float32 (see `training_sets.linear_images`), at
    least 128 pixels on the shorter side; `rows`, `estimators` (see `ROWS`,
    `estimators.ESTIMATORS`); `seeds`: each seed draws new CG views, lights, noise and estimator
    initialisations (the folds stay); `n`: synthetic training images per set;
    `illuminant_model`: the kind fitted for 'fitted', 'published', 'real_profile_light' and
    'other_content' (`g2r-fit-profile --illuminant-model`); `single_light`: the kind for 'single';
    `lights`: fit those rows' model to this many training files' lights only (a random subset:
    the number-of-DNGs ablation, supplement Table S6); `other`: (RealSet, SensorProfile) of other
    real scenes for 'other_content'; `progress`: a callable taking one line of text, or a
    `downstream.base.progress.Progress` (advanced by one per estimator trained:
    `trainings(...)` of them); `workers`: rows of a fold built and trained side by side in
    threads (None: up to `MAX_WORKERS`, at most the CPU count; the errors do not depend on it);
    `labelled`: the number of labelled real files 'real' and the augmented rows train on (None:
    all the training folds'; the curve of issue 48); `cache`: a `downstream.base.cache.DownstreamCache`
    whose stored estimates replace the trainings it holds (None: every estimator is trained).

    **Returns:** an `ExperimentResult`.
    """
    unknown = [r for r in rows if r not in ROWS]
    if unknown:
        raise ValueError(f"unknown rows {unknown}; expected some of {', '.join(ROWS)}")
    if len(real.images) < 2 * folds:
        raise ValueError(f"{real.name}: {len(real.images)} real images are too few for {folds} folds")
    say = progress or (lambda message: None)
    linear = cg_images if cg_images and np.asarray(cg_images[0]).dtype == np.float32 else _sets.linear_images(cg_images)
    start = time.perf_counter()
    sets = _Sets(real, profile, linear, n=n, illuminant_model=illuminant_model, other=other,
                 single_light=single_light, lights=lights, labelled=labelled)
    errors = {(r, e): [] for r in rows for e in estimators}
    recipes = {(r, e): [] for r in rows if r in AUGMENTED_ROWS for e in estimators}
    choice_scores = {key: [] for key in recipes}
    fold_sets = folds_of(len(real.images), folds, 0, groups=real.groups)
    workers = max(1, min(len(rows), workers or min(MAX_WORKERS, os.cpu_count() or 1)))
    unit_key = _unit_keys(real, profile, linear, n=n, folds=folds, illuminant_model=illuminant_model,
                          single_light=single_light, lights=lights, labelled=labelled, other=other)
    for seed in seeds:
        per_fold = {key: [] for key in errors}
        for fold, test in enumerate(fold_sets):
            train = np.setdiff1d(np.arange(len(real.images)), test)
            sets.prepare(rows, train, fold, seed)

            def row_errors(row):
                keys = {e: unit_key(row, e, test, seed) for e in estimators}
                stored = {e: cache.get(keys[e]) for e in estimators} if cache is not None else {}
                built = None if stored and all(v is not None for v in stored.values()) else sets.fold_work.get(
                    ("set", row), lambda: sets.build(row, train, fold, seed))
                out = {}
                for estimator in estimators:
                    if stored.get(estimator) is not None:
                        estimates = stored[estimator]["estimates"]
                        if (row, estimator) in recipes:
                            recipes[(row, estimator)].append(str(stored[estimator]["recipe"]))
                            choice_scores[(row, estimator)].append(json.loads(str(stored[estimator].get("scores", "{}"))))
                    else:
                        predict = _trained(estimator, built, 1000 * seed + fold, recipes.get((row, estimator)),
                                           sets.fold_work, row, AUGMENTED_ROWS.get(row) in rows,
                                           choice_scores.get((row, estimator)))
                        estimates = predict(real.images[test])
                        if cache is not None:
                            chosen = recipes[(row, estimator)][-1] if (row, estimator) in recipes else ""
                            scores = choice_scores[(row, estimator)][-1] if (row, estimator) in recipes else {}
                            cache.put(keys[estimator], {"estimates": estimates, "recipe": np.asarray(chosen),
                                                        "scores": np.asarray(json.dumps(scores))})
                    out[estimator] = angular_error_degrees(estimates, real.illuminants[test])
                    advance(progress, 1, f"colour check: seed {seed}, fold {fold + 1}, {row}, {estimator}")
                return out

            with ThreadPoolExecutor(workers) as pool:   # rows are independent: train them side by side
                for row, out in zip(rows, pool.map(row_errors, rows)):
                    for estimator in estimators:
                        per_fold[(row, estimator)].append(out[estimator])
            say(f"{real.name}: seed {seed}, fold {fold + 1}/{folds} done ({time.perf_counter() - start:.0f} s)")
        for key, parts in per_fold.items():
            errors[key].append(np.concatenate(parts))
    return ExperimentResult(camera=real.name, rows=tuple(rows), estimators=tuple(estimators), seeds=tuple(seeds),
                            errors=errors, seconds=time.perf_counter() - start, notes=list(sets.notes),
                            recipes=recipes, choice_scores=choice_scores, labelled=labelled, files=len(real.images))


def _unit_keys(real: RealSet, profile, cg_linear, **options):
    """key(row, estimator, test, seed) of one training's stored estimates (`downstream.base.cache`):
    the code, the real images and labels, the CG images, the profile and the options."""
    from g2r_jax.downstream.base.cache import code_digest, key_of, profile_text

    other = options.pop("other")
    base = key_of(code_digest(), "colour check", real.images, real.illuminants, list(cg_linear), profile_text(profile),
                  sorted(options.items()),
                  None if other is None else (other[0].images, other[0].illuminants, profile_text(other[1])))
    return lambda row, estimator, test, seed: key_of(base, row, estimator, np.asarray(test), seed)


def _trained(estimator: str, built, seed: int, recipes: Optional[list], fold_work: Once, row: str,
             shares: bool = False, scores: Optional[list] = None):
    """A predictor trained on a row's set: an (images, lights) pair, or an augmented set (its
    recipe chosen on the training files and appended to `recipes`, the candidates' cross-validated
    means to `scores`). A row's estimator is trained
    once per fold (`fold_work`); with `shares` (its synthetic row is trained too) the augmented
    row reuses that row's estimator as its 'synthetic' candidate and its pretraining (the same
    set, seed and training: the same network, one training fewer per candidate)."""
    from g2r_jax.downstream.illuminant.augmentation import AugmentedSet, train_chosen
    from g2r_jax.downstream.illuminant.estimators import train_estimator

    if not isinstance(built, AugmentedSet):
        return fold_work.get(("trained", row, estimator), lambda: train_estimator(estimator, *built, seed=seed))
    synthetic = fold_work.get(("trained", AUGMENTED_ROWS[row], estimator),
                              lambda: train_estimator(estimator, *built.synthetic, seed=seed)) if shares else None
    predict, recipe, cross_validated = train_chosen(estimator, built, seed=seed, synthetic=synthetic)
    recipes.append(str(recipe))
    if scores is not None:
        scores.append({name: round(float(value), 4) for name, value in cross_validated.items()})
    return predict
