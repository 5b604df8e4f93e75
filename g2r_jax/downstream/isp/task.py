"""The paper's third downstream task, a neural ISP (Graphics2RAW, Seo et al. ICCV 2023, Sec. 4.5
and supplement S1.3, Tables S2, S3, S5, S6): a UNet learns RAW -> display sRGB on synthetic
pairs and is tested on the camera's real pairs, beside the same UNet trained on UPI's synthetic
RAW (Brooks et al. CVPR 2019) and on the real pairs themselves (cross-validated).

Protocol: one fixed developer (`g2r_jax.io.reference_render`, LibRaw at each file's AsShotNeutral)
makes the sRGB target of every DNG, real or synthetic; the network sees the packed RAW alone, so
it must learn the white balance too (`downstream.isp.pairs` makes the pairs, `downstream.isp.net`
has the UNet and the measures). The real files are split into `folds` folds
(`g2r_jax.measure.folds_of`, the colour check's folds); for each fold and seed every row makes
its training pairs from the training folds (never the test fold), one UNet per row is trained
(`downstream.base.training.fit`) and tested on the fold's real pairs: PSNR, SSIM and CIEDE2000 per
image, pooled over folds, then the mean over seeds and the seeds' spread.

Rows (`ROWS`; the colour check's names):
- upi: UPI on the CG views: its random camera matrix and gains; the DNG carries the camera's tags
  and AsShotNeutral = the inverse of UPI's white-balance gains;
- fitted: the product, g2r_jax as `g2r-fit-profile` makes it: the lights fitted to the training
  folds' as-shot neutrals (`product.fitted_illuminants`) and the content model (the profile's
  own when it carries one, else the 'cast' model fitted to the training folds' thumbnails only,
  `product.candidate_model(product.FITTED, ...)`), which recolours every CG frame
  before it is made RAW: the target is developed from the DNG that carries the adapted frame;
  and the files' fine texture (`content.texture`: the profile's own when its content model
  carries one, else that of the training folds' files) drawn onto every view: the CG frames are
  flat at the task's scale where real scenes are not, and a UNet trained on flat views errs at
  the real files' edges (docs/pages/validation/downstream_isp.md, "The CG frames' texture");
- fitted_no_content: control: the same lights, no content model (`pipeline.without_content`);
- shipped: the profile as given (out of the box; only when the caller asks for it), with the
  texture its content model carries (a shipped profile's: the prior's, `content.prior.SCENE_TEXTURE`);
- single: g2r_jax from one training file (its light, the content model and texture of its scene);
- real: the real training folds' pairs;
- real_plus_fitted: augmentation (issue 48): the real training folds' pairs and the 'fitted'
  row's pairs in one set, so that every batch draws from both, about in proportion (the real
  pairs keep their masks; every pixel of a synthetic pair counts); the kept round is chosen on a
  held-out share of that set, as for every row; not in the user's check by default;
- real_pretrained: augmentation (issue 48): the 'fitted' row's UNet (trained on g2r_jax pairs)
  fine-tuned on the real training folds' pairs (the same schedule, from its weights, the round
  kept on a held-out share of the real pairs); its pretraining is one more training of the
  same length, so it has twice the real row's compute; not in the user's check by default;
- real_profile_light: control: the real training thumbnails rendered to linear sRGB at their
  measured white (`training_sets.real_to_linear_srgb`) and made RAW again through g2r_jax with
  the fitted lights, no content model; with masks, its inputs hold the real pairs' own values
  wherever the masks hide the targets (the real pairs' missing pixels are written white before
  the thumbnails are binned, so their tiles there hold partly white values; a control whose
  tiles were written wholly white instead trained 0.58 dB below one holding the real values,
  Canon1DsMkIII, 3 seeds, its lights and exposures those of the real files: the real row's
  figure within its seeds' spread with the real values).
  The profile's share of the gap to real training is real_profile_light - real, the CG content's
  is fitted - real_profile_light.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Callable, Optional, Sequence

import numpy as np

from g2r_jax.downstream.base import thumbnails as _thumbnails
from g2r_jax.downstream.base import training_sets as _sets
from g2r_jax.downstream.base.progress import advance
from g2r_jax.downstream.base.real_sets import RealSet
from g2r_jax.downstream.isp import pairs as _pairs
from g2r_jax.downstream.isp.error_parts import PARTS
from g2r_jax.downstream.isp.net import IspTraining

ROWS = {
    "upi": "UPI (Brooks et al. 2019)",
    "fitted": "g2r_jax as g2r-fit-profile makes it (lights, content model)",
    "fitted_no_content": "control: g2r_jax, lights fitted, no content model",
    "shipped": "g2r_jax, profile as given",
    "single": "g2r_jax, one DNG",
    "real": "real training files",
    "real_plus_fitted": "real training files + g2r_jax (fitted), mixed",
    "real_pretrained": "real training files, pretrained on g2r_jax (fitted)",
    "real_profile_light": "control: real, lights from the model",
}
OPTIONAL_ROWS = ("shipped", "real_plus_fitted", "real_pretrained")   # 'shipped' when the caller gives a profile
PRETRAINED_ON = {"real_pretrained": ("fitted", "real")}   # row: (the row it starts from, the row it fine-tunes on)
DEFAULT_ROWS = tuple(r for r in ROWS if r not in OPTIONAL_ROWS)
METRICS = {"psnr": "PSNR (dB)", "ssim": "SSIM", "delta_e": "ΔE2000"}
HIGHER_IS_BETTER = {"psnr": True, "ssim": True, "delta_e": False}
MEASURES = {**METRICS, **PARTS}    # the metrics and the diagnoses of where the colour error lies (`error_parts`)
EXAMPLES = 3   # real test files kept for the figure (first seed)


@dataclasses.dataclass
class IspResult:
    """Per-image measures of every row: `metrics[(row, metric)]` one array per seed of every real
    test image's value (folds concatenated); `skipped` the real files left out [(name, reason)];
    `examples` the figure's data ({'names', 'target', 'predicted': {row: images}})."""

    camera: str
    rows: tuple
    seeds: tuple
    folds: int
    n: int
    size: int
    metrics: dict
    images: int = 0
    seconds: float = 0.0
    notes: list = dataclasses.field(default_factory=list)
    skipped: list = dataclasses.field(default_factory=list)
    examples: dict = dataclasses.field(default_factory=dict)
    training: dict = dataclasses.field(default_factory=dict)
    unmasked: dict = dataclasses.field(default_factory=dict)   # with masks: the same networks over every pixel

    def summary(self, row: str, metric: str) -> dict:
        """The mean over images, folds and seeds of `metric` for `row`, each seed's mean, their
        range and standard deviation.

        **Arguments:** `row` in `rows`; `metric` in `METRICS`. **Returns:** a dict."""
        per_seed = [np.asarray(a, np.float64) for a in self.metrics[(row, metric)]]
        means = [float(np.nanmean(a)) for a in per_seed]    # NaN: a test image whose mask holds nothing
        return {"mean": float(np.nanmean(np.concatenate(per_seed))),
                "median": float(np.nanmedian(np.concatenate(per_seed))),
                "seed_means": means, "seed_min": min(means), "seed_max": max(means),
                "seed_sd": float(np.std(means, ddof=1)) if len(means) > 1 else 0.0}

    def to_dict(self) -> dict:
        """Everything but the figure's images, JSON-ready. **Returns:** a dict."""
        return {"camera": self.camera, "rows": list(self.rows), "seeds": list(self.seeds), "folds": self.folds,
                "n": self.n, "size": self.size, "images": self.images, "seconds": self.seconds,
                "notes": list(self.notes), "skipped": [{"path": p, "reason": r} for p, r in self.skipped],
                "training": dict(self.training),
                "summary": {f"{r}/{m}": self.summary(r, m) for r in self.rows for m in MEASURES if (r, m) in self.metrics},
                "summary_unmasked": {f"{r}/{m}": float(np.mean(np.concatenate(self.unmasked[(r, m)])))
                                     for r in self.rows for m in METRICS if self.unmasked},
                "sentence": self.sentence()}

    def table(self) -> str:
        """Markdown: one line per row, the mean of each measure (pooled over folds and seeds) and
        the seeds' range. **Returns:** the table's text."""
        out = ["| training set | PSNR (dB) | SSIM | ΔE2000 | seeds: PSNR | seeds: ΔE2000 |", "|---|---|---|---|---|---|"]
        for row in self.rows:
            s = {m: self.summary(row, m) for m in METRICS}
            out.append(f"| {ROWS[row]} (`{row}`) | {s['psnr']['mean']:.2f} | {s['ssim']['mean']:.3f} | "
                       f"{s['delta_e']['mean']:.2f} | {s['psnr']['seed_min']:.2f}-{s['psnr']['seed_max']:.2f} | "
                       f"{s['delta_e']['seed_min']:.2f}-{s['delta_e']['seed_max']:.2f} |")
        return "\n".join(out)

    def parts_table(self) -> str:
        """Markdown: per row, ΔE2000 and what is left of it after each test image's best white
        balance and best 3 x 3 colour correction (`error_parts`), and the white balance's share.
        **Returns:** the table's text."""
        out = ["| training set | ΔE2000 | after best gains | after best 3 x 3 | white balance's share |",
               "|---|---|---|---|---|"]
        for row in self.rows:
            if (row, "delta_e_balance") not in self.metrics:
                continue
            e, g, c = (self.summary(row, m)["mean"] for m in ("delta_e", "delta_e_balance", "delta_e_colour"))
            out.append(f"| {ROWS[row]} (`{row}`) | {e:.2f} | {g:.2f} | {c:.2f} | {(e - g) / max(e, 1e-12):.0%} |")
        return "\n".join(out)

    def compare(self, a: str, b: str, metric: str) -> tuple:
        """(mean of `a` - mean of `b`, whether their seeds' ranges overlap) for `metric`.

        **Arguments:** two rows; a metric. **Returns:** (float, bool)."""
        sa, sb = self.summary(a, metric), self.summary(b, metric)
        overlap = sa["seed_min"] <= sb["seed_max"] and sb["seed_min"] <= sa["seed_max"] and len(self.seeds) > 1
        return sa["mean"] - sb["mean"], overlap

    def sentence(self) -> str:
        """One sentence: the product row against UPI and real training (PSNR, ΔE2000), and the
        profile's and the CG content's shares of the gap; a difference whose seeds' ranges
        overlap is called within training noise. **Returns:** the sentence."""
        return _sentence(self)

    def figure(self, path) -> bool:
        """Predicted against target images of a few real test files, one column per row (PNG,
        written atomically). **Arguments:** `path`. **Returns:** False when matplotlib is absent
        or there is nothing to show, else True."""
        return _figure(self, path)


def _psnr_phrase(result, a: str, b: str) -> str:
    diff, overlap = result.compare(a, b, "psnr")
    if overlap:
        return f"within training noise of {_name(b)} ({diff:+.2f} dB)"
    return f"{abs(diff):.2f} dB {'above' if diff > 0 else 'below'} {_name(b)}"


def _delta_phrase(result, a: str, b: str) -> str:
    diff, overlap = result.compare(a, b, "delta_e")
    ratio = result.summary(a, "delta_e")["mean"] / max(result.summary(b, "delta_e")["mean"], 1e-12)
    if overlap:
        return f"ΔE2000 within training noise of {_name(b)} ({ratio:.2f}x)"
    return f"ΔE2000 {ratio:.2f}x {_name(b)}'s"


def _name(row: str) -> str:
    return {"upi": "UPI", "real": "real training", "fitted": "g2r_jax (fitted)", "shipped": "g2r_jax as shipped",
            "single": "g2r_jax from one DNG", "fitted_no_content": "g2r_jax without content model",
            "real_profile_light": "real scenes under the fitted lights",
            "real_plus_fitted": "real training + g2r_jax",
            "real_pretrained": "real training pretrained on g2r_jax"}.get(row, row)


def _sentence(result: IspResult) -> str:
    rows = result.rows
    product = next((r for r in ("fitted", "shipped", "fitted_no_content", "single") if r in rows), None)
    head = (f"Neural ISP on {result.camera or 'the real files'} ({result.images} real files, {result.folds} folds, "
            f"{len(result.seeds)} seed(s))")
    if product is None:
        return head + ": " + "; ".join(f"{_name(r)} {result.summary(r, 'psnr')['mean']:.2f} dB, ΔE2000 "
                                       f"{result.summary(r, 'delta_e')['mean']:.2f}" for r in rows) + "."
    s = {m: result.summary(product, m)["mean"] for m in METRICS}
    parts = [f"{head}: {_name(product)} reaches {s['psnr']:.2f} dB and ΔE2000 {s['delta_e']:.2f}"]
    for other in ("upi", "real"):
        if other in rows:
            parts.append(f"{_psnr_phrase(result, product, other)}, {_delta_phrase(result, product, other)}")
    text = "; ".join(parts)
    if {"real", "real_profile_light"} <= set(rows) and product == "fitted":
        profile_db = -result.compare("real_profile_light", "real", "psnr")[0]
        content_db = -result.compare("fitted", "real_profile_light", "psnr")[0]
        profile_de = result.compare("real_profile_light", "real", "delta_e")[0]
        content_de = result.compare("fitted", "real_profile_light", "delta_e")[0]
        text += (f"; of the gap to real training the profile's share (real scenes under the fitted lights) is "
                 f"{profile_db:+.2f} dB / ΔE2000 {profile_de:+.2f} and the CG content's {content_db:+.2f} dB / "
                 f"ΔE2000 {content_de:+.2f}")
    return text + "."


def _figure(result: IspResult, path) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    examples = result.examples
    if not examples or not len(examples.get("names", ())):
        return False
    import io

    from g2r_jax.io.atomic import atomic_write_bytes

    rows = [r for r in result.rows if r in examples["predicted"]]
    columns = ["target"] + rows
    count = len(examples["names"])
    fig, axes = plt.subplots(count, len(columns), figsize=(1.6 * len(columns), 1.7 * count), squeeze=False)
    for i in range(count):
        for j, column in enumerate(columns):
            image = examples["target"][i] if column == "target" else examples["predicted"][column][i]
            axes[i, j].imshow(np.clip(image, 0, 1), interpolation="nearest")
            axes[i, j].set_xticks([])
            axes[i, j].set_yticks([])
            if i == 0:
                axes[i, j].set_title(column, fontsize=7)
            if j == 0:
                axes[i, j].set_ylabel(str(examples["names"][i])[-18:], fontsize=6)
    fig.suptitle(f"Neural ISP, {result.camera}: LibRaw target and each row's UNet (seed {result.seeds[0]})", fontsize=8)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    plt.close(fig)
    atomic_write_bytes(path, buffer.getvalue())
    return True


def _repeat_to(n: int, *arrays):
    reps = max(1, -(-n // len(arrays[0])))
    return [np.concatenate([a] * reps)[: max(n, len(arrays[0]))] for a in arrays]


class _RowSets:
    """Builds and caches each row's training pairs for one camera, fold and seed."""

    def __init__(self, real: RealSet, pairs: tuple, profile, shipped, cg_linear, *, n, size, view_size,
                 illuminant_model, single_light, lights, masks=None, texture=True):
        self.real, self.pairs, self.profile, self.shipped = real, pairs, profile, shipped
        self.texture = texture    # the 'fitted' and 'single' rows' views get their files' texture (`content.texture`)
        self.cg, self.n, self.size, self.view_size = cg_linear, n, size, view_size
        self.illuminant_model, self.single_light, self.lights = illuminant_model, single_light, lights
        self.masks = masks        # (N, size, size) of the real pairs: out of the real rows' loss
        self.cache, self.notes = {}, []

    def _cached(self, key, make):
        if key not in self.cache:
            self.cache[key] = make()
        return self.cache[key]

    def views(self, seed):
        return self._cached(("views", seed), lambda: _sets.cg_views(self.cg, self.n, seed, size=self.view_size))

    def fitted(self, train, fold, seed):
        """The profile with its lights fitted to the training folds' (or `lights` of them; 0: its own)."""
        from g2r_jax.downstream.base.product import fitted_illuminants

        def make():
            lights = self.real.illuminants[train]
            if self.lights == 0:
                return self.profile
            if self.lights is not None and self.lights < len(lights):
                pick = np.random.default_rng(1000 * seed + 10 * fold + 9).choice(len(lights), self.lights, replace=False)
                lights = lights[pick]
            return fitted_illuminants(self.profile, lights, self.illuminant_model, seed)
        return self._cached(("fitted", fold, seed), make)

    def content_model(self, images, lights, seed, where: str):
        """The profile's own content model, else the FITTED family fitted to `images` (None when
        their cast cannot be fitted, as g2r-fit-profile then writes none). With the texture, the
        whole model, applied after the texture: on the training data of three cameras (`--inner`,
        3 seeds) the ISP trained to ΔE2000 7.20 so against 7.70 on the median cast then the
        texture and 8.28 on the whole model then the texture (docs/pages/validation/downstream_isp.md,
        "The CG frames' texture"). Without it, of a 'scenes' model its median cast only
        (`content.as_cast`, `g2r-convert --content-cast-only`): on Canon1DsMkIII (3 seeds) the ISP
        trained 0.48 dB better on the cast than on the scenes model (docs/pages/validation/content_model.md)."""
        from g2r_jax.content import as_cast, describe
        from g2r_jax.downstream.base import product

        def cast_of(model):     # with the texture the whole model (see the docstring), without it its cast
            return as_cast(model) if model.family == "scenes" and not self.texture else model

        own = getattr(self.profile, "content", None)
        if own is not None:
            self.notes.append(f"g2r_jax rows: the profile's own content model ({describe(cast_of(own))}), used as given")
            return cast_of(own)
        try:
            model = cast_of(product.candidate_model(product.FITTED, images, lights, self.views(seed), self.profile))
        except ValueError as error:
            self.notes.append(f"{where}: no content model ({error})")
            return None
        self.notes.append(f"{where}: {describe(model)}, fitted to {len(images)} training file(s)' scenes")
        return model

    def texture_of(self, images, where: str):
        """The texture the profile's content model carries (g2r-fit-profile's, of its files), else
        that of `images` (`content.texture.fit_texture`); None when the run adds none."""
        if not self.texture:
            return None
        from g2r_jax.content.texture import fit_texture

        own = getattr(getattr(self.profile, "content", None), "texture", None)
        if own is not None:
            self.notes.append(f"g2r_jax rows' texture: the profile's own ({own.source or 'its files'}, "
                              f"{own.grid} pixels across), added to every CG view")
            return own
        try:
            model = fit_texture(images, source=where)
        except ValueError as error:
            self.notes.append(f"{where}: no texture ({error})")
            return None
        self.notes.append(f"g2r_jax rows' texture: the log texture of their files at {model.grid} pixels across "
                          f"(content.texture), added to every CG view")
        return model

    def _g2r(self, views, profile, salt, model=None, *, as_given: bool = False, saturated=None, texture=None):
        """g2r_jax pairs of `views` (times a draw of `texture` first, when given, then through
        `model`, when given) with `profile`: as given (its content model applied as it says) or
        without its content model."""
        import jax

        from g2r_jax.content.texture import add_texture
        from g2r_jax.downstream.base.product import adapted_views
        from g2r_jax.pipeline import without_content

        if texture is not None:        # the texture is the scene's, before what the content model does to its light
            views = np.asarray(add_texture(texture, views, jax.random.PRNGKey(salt + 91)))
        views = views if model is None else adapted_views(model, views, salt)
        return _pairs.g2r_pairs(views, profile if as_given else without_content(profile), salt, size=self.size,
                                saturated=saturated)

    def build(self, row: str, train: np.ndarray, fold: int, seed: int):
        salt = 1000 * seed + 10 * fold
        if row == "real":
            return (self.pairs[0][train], self.pairs[1][train]) + (() if self.masks is None else (self.masks[train],))
        if row == "upi":
            return self._cached(("upi", seed), lambda: _pairs.upi_pairs(
                _sets.linear_to_srgb_views(self.views(seed)), self.profile, seed + 1, size=self.size))
        if row == "shipped":
            texture = getattr(getattr(self.shipped, "content", None), "texture", None) if self.texture else None
            return self._cached(("shipped", seed), lambda: self._g2r(self.views(seed), self.shipped, seed + 2,
                                                                     as_given=True, texture=texture))
        if row == "single":
            pick = int(train[np.random.default_rng(salt + 3).integers(len(train))])
            from g2r_jax.downstream.base.product import fitted_illuminants

            one = slice(pick, pick + 1)
            profile = fitted_illuminants(self.profile, self.real.illuminants[one], self.single_light)
            model = self.content_model(self.real.images[one], self.real.illuminants[one], seed,
                                       f"one-DNG row, seed {seed}, fold {fold + 1}, file {pick}")
            return self._g2r(self.views(seed), profile, salt + 3, model,
                             texture=self.texture_of(self.real.images[one], f"one training file ({pick})"))
        if row == "real_plus_fitted":
            return _mixed(self.build("real", train, fold, seed), self.build("fitted", train, fold, seed))
        fitted = self.fitted(train, fold, seed)
        if row == "fitted":
            def make():
                model = self.content_model(self.real.images[train], self.real.illuminants[train], seed,
                                           f"content model, seed {seed}, fold {fold + 1}")
                texture = self.texture_of(self.real.images[train], f"{len(train)} training files, fold {fold + 1}")
                return self._g2r(self.views(seed), fitted, salt + 4, model, texture=texture)
            return self._cached(("fitted pairs", fold, seed), make)
        if row == "fitted_no_content":
            return self._g2r(self.views(seed), fitted, salt + 4)
        if row == "real_profile_light":
            views = _sets.real_to_linear_srgb(self.real.images[train], self.real.illuminants[train], self.profile,
                                              size=self.real.images.shape[1])
            views = np.stack([_thumbnails.area_average(v, self.view_size) for v in views])
            if self.masks is None:
                views, = _repeat_to(self.n, views)
                return self._g2r(views, fitted, salt + 8)
            # where the masks hide the targets, the inputs hold the real pairs' own values (their
            # missing pixels' tiles, partly white): the network sees there what the real pairs show
            tiles = _pairs.missing_tiles(self.real.images[train], size=self.size)
            views, masks, tiles, inputs = _repeat_to(self.n, views, self.masks[train], tiles, self.pairs[0][train])
            packed, targets = self._g2r(views, fitted, salt + 8, saturated=tiles)
            return np.where(~masks[:, ::2, ::2, None], inputs, packed), targets, masks
        raise ValueError(f"unknown row {row!r}; expected one of {', '.join(ROWS)}")


def _mixed(real: tuple, synthetic: tuple) -> tuple:
    """One training set of real and synthetic pairs (packed, targets[, masks]): the real pairs'
    masks kept, the synthetic pairs measured on every pixel."""
    if len(real) > 2:
        synthetic = (*synthetic[:2], np.ones(synthetic[1].shape[:3], bool))
    return tuple(np.concatenate([a, b]) for a, b in zip(real, synthetic))


def trainings(rows, seeds, folds: int) -> int:
    """How many UNets `run_isp_task` trains (its units of progress). **Arguments:** `rows`,
    `seeds` (sequences), `folds`. **Returns:** an int."""
    return len(rows) * len(seeds) * folds


def _real_pairs(real: RealSet, dngs, size: int, folds: int, masks=None):
    """(the real set and its pairs (packed, targets[, masks]) without the files the renderer
    cannot develop, their sources, skipped)."""
    sources = list(real.files) if dngs is None else list(dngs)
    if len(sources) != len(real.images):
        raise ValueError(f"{real.name}: {len(sources)} DNGs for {len(real.images)} real images (give one per image)")
    if masks is not None and np.shape(masks) != (len(sources), size, size):
        raise ValueError(f"{real.name}: masks of shape {np.shape(masks)}, expected {(len(sources), size, size)}")
    packed, targets, kept, skipped = _pairs.pairs_of(sources, size)
    if len(kept) < len(sources):
        groups = None if real.groups is None else np.asarray(real.groups)[kept]
        real = dataclasses.replace(real, images=real.images[kept], illuminants=real.illuminants[kept],
                                   files=tuple(np.asarray(real.files, object)[kept]) if real.files else (), groups=groups)
    distinct = len(kept) if real.groups is None else len(np.unique(real.groups))
    if distinct < 2 * folds:
        raise ValueError(f"{real.name or 'the real set'}: {distinct} usable real DNG(s) (distinct files; "
                         f"{len(skipped)} left out) are too few for the neural-ISP task's {folds} folds: it needs at "
                         f"least {2 * folds}")
    pairs = (packed, targets) if masks is None else (packed, targets, np.asarray(masks, bool)[kept])
    return real, pairs, [s for i, s in enumerate(sources) if i in set(kept)], skipped


def _unit_keys(pairs, cg_linear, profile, shipped, **options):
    """key(row, test, seed) of one UNet's stored outcome (`downstream.base.cache`): the code, the real
    pairs (and masks), the CG images, the profiles and the options."""
    from g2r_jax.downstream.base.cache import code_digest, key_of, profile_text

    base = key_of(code_digest(), "isp task", list(pairs), list(cg_linear), profile_text(profile), profile_text(shipped),
                  sorted(options.items()))
    return lambda row, test, seed: key_of(base, row, np.asarray(test), seed)


def _outcome(model, pairs, test, shown) -> dict:
    """What the run keeps of one trained UNet: its measures on the test fold (masked, and over every
    pixel when there are masks) and its predictions of the figure's files in that fold."""
    from g2r_jax.downstream.isp import net
    from g2r_jax.downstream.isp.error_parts import error_parts

    predicted = net.predict(model, pairs[0][test])
    mask = pairs[2][test] if len(pairs) > 2 else None
    out = {f"masked_{k}": v for k, v in net.measure(predicted, pairs[1][test], mask).items()}
    out.update({f"masked_{k}": v for k, v in error_parts(predicted, pairs[1][test], mask).items()})
    if mask is not None:
        out.update({f"all_{k}": v for k, v in net.measure(predicted, pairs[1][test]).items()})
    slots = [k for k, index in enumerate(shown) if index in test]
    out["example_slots"] = np.asarray(slots, int)
    out["examples"] = predicted[[int(np.searchsorted(test, shown[k])) for k in slots]]
    return out


def _fold_outcomes(sets, rows, pairs, train, test, fold, seed, shown, training, cache, key) -> dict:
    """{row: outcome} of one fold and seed: from the cache where it holds them, the other rows'
    UNets trained (together, as `net.train_many` does) and stored."""
    from g2r_jax.downstream.isp import net

    outcomes = {row: cache.get(key(row)) if cache is not None else None for row in rows}
    todo = [row for row in rows if outcomes[row] is None]
    plain = [row for row in todo if row not in PRETRAINED_ON]
    seed_of = 1000 * seed + fold
    models = dict(zip(plain, net.train_many([sets.build(row, train, fold, seed) for row in plain], [seed_of] * len(plain),
                                            training))) if plain else {}
    for row in todo:
        if row in PRETRAINED_ON:
            start, on = PRETRAINED_ON[row]
            if start not in models:        # its outcome may be stored, its network is not
                models[start] = net.train_many([sets.build(start, train, fold, seed)], [seed_of], training)[0]
            models[row] = net.train_many([sets.build(on, train, fold, seed)], [seed_of], training,
                                         initial=[models[start]])[0]
    for row in todo:
        outcomes[row] = _outcome(models[row], pairs, test, shown)
        if cache is not None:
            cache.put(key(row), outcomes[row])
    return outcomes


def _examples(fold_sets, count: int = EXAMPLES) -> np.ndarray:
    """The real files shown in the figure: the first test file of each fold, then the next ones."""
    order = [int(i) for column in zip(*[list(f) for f in fold_sets]) for i in column] if fold_sets else []
    return np.asarray(order[:count], int)


def run_isp_task(real: RealSet, profile, cg_images, *, rows: Sequence[str] = DEFAULT_ROWS, seeds=(0, 1),
                 folds: int = 3, n: int = 200, size: int = _pairs.WORKING_SIZE, dngs=None, shipped=None,
                 lights: Optional[int] = None, illuminant_model: str = "auto", single_light: str = "auto",
                 training: IspTraining = IspTraining(), masks=None, cache=None, texture: bool = True,
                 progress: Optional[Callable[[str], None]] = None) -> IspResult:
    """Train the ISP UNet on each row's pairs, test it on the real pairs (module docstring).

    **Arguments:** `real`: the real set (`real_sets.RealSet`; its `files` are the DNGs, e.g.
    `load_dng_folder`'s, its thumbnails and illuminants feed the fitted lights and content
    model); `profile`: the camera's `SensorProfile`; `cg_images`: CG images, sRGB-coded uint8
    (H, W, 3) or linear float32 (`training_sets.linear_images`); `rows` (see `ROWS`); `seeds`:
    each seed draws new CG views, lights and UNet initialisations (the folds stay); `folds`;
    `n`: synthetic training pairs per set; `size`: the target's side; `dngs`: one DNG per real
    image instead of `real.files` (paths, or `pairs.DngSource` in memory, e.g.
    `pairs.thumbnail_sources` of the NUS thumbnails); `shipped`: the profile of the
    'shipped' row (default `profile`); `lights`: fit the lights of 'fitted', 'fitted_no_content'
    and 'real_profile_light' to this many random training files only (0: the profile's own:
    the number-of-DNGs ablation, supplement Table S6); `illuminant_model`, `single_light`: the
    kinds fitted (`g2r-fit-profile --illuminant-model`); `training`: the UNet and its training
    (`net.IspTraining`); `masks`: (N, size, size) bool per real DNG, True where its target
    holds what the real data holds (`pairs.thumbnail_masks` of the NUS thumbnails: their masked
    chart and saturated pixels are out of the real rows' loss and out of every row's measures;
    None for real DNGs, whose clipped pixels are content); `cache`: a `downstream.base.cache.
    DownstreamCache` whose stored outcomes (each network's measures and example images) replace
    the trainings it holds (None: every UNet is trained); `texture`: the 'fitted' and 'single' rows'
    CG views get the fine texture of their real files (`content.texture`; False: none, as before
    issue 49's measurement); `progress`: a callable taking a line of text, or a
    `downstream.base.progress.Progress` (advanced by one per UNet: `trainings(...)` of them).

    **Returns:** an `IspResult`. **Raises:** ValueError for unknown rows or a set too small for
    the folds (saying how many files it needs).
    """
    from g2r_jax.measure import folds_of

    unknown = [r for r in rows if r not in ROWS]
    if unknown:
        raise ValueError(f"unknown rows {unknown}; expected some of {', '.join(ROWS)}")
    say = progress or (lambda line: None)
    start = time.perf_counter()
    real, pairs, sources, skipped = _real_pairs(real, dngs, size, folds, masks)
    test_masks = pairs[2] if len(pairs) > 2 else None
    for name, reason in skipped:
        say(f"left out {name}: {reason}")
    linear = cg_images if len(cg_images) and np.asarray(cg_images[0]).dtype == np.float32 else _sets.linear_images(cg_images)
    sets = _RowSets(real, pairs, profile, shipped if shipped is not None else profile, linear, n=n, size=size,
                    view_size=size // 2, illuminant_model=illuminant_model,
                    single_light=single_light, lights=lights, masks=test_masks, texture=texture)
    fold_sets = folds_of(len(real.images), folds, 0, groups=real.groups)
    shown = _examples(fold_sets)
    names = [getattr(sources[i], "name", str(sources[i])) for i in shown]
    examples = {"names": names, "target": pairs[1][shown], "predicted": {r: np.zeros_like(pairs[1][shown]) for r in rows}}
    metrics = {(r, m): [] for r in rows for m in MEASURES}
    unmasked = {(r, m): [] for r in rows for m in METRICS} if test_masks is not None else {}
    unit_key = _unit_keys(pairs, linear, profile, sets.shipped, n=n, size=size, lights=lights, folds=folds,
                          illuminant_model=illuminant_model, single_light=single_light, texture=texture,
                          training=sorted(dataclasses.asdict(training).items()))
    for seed in seeds:
        per_fold = {key: [] for key in metrics}
        per_fold_unmasked = {key: [] for key in unmasked}
        for fold, test in enumerate(fold_sets):
            train = np.setdiff1d(np.arange(len(real.images)), test)
            outcomes = _fold_outcomes(sets, rows, pairs, train, test, fold, seed, shown, training, cache,
                                      lambda row: unit_key(row, test, seed))
            for row in rows:
                outcome = outcomes[row]
                for metric in MEASURES:
                    per_fold[(row, metric)].append(outcome[f"masked_{metric}"])
                    if unmasked and metric in METRICS:
                        per_fold_unmasked[(row, metric)].append(outcome[f"all_{metric}"])
                if seed == seeds[0]:
                    for slot, image in zip(outcome["example_slots"], outcome["examples"]):
                        examples["predicted"][row][int(slot)] = image
                advance(progress, 1, f"ISP task: seed {seed}, fold {fold + 1}, {row}")
            say(f"{real.name}: ISP seed {seed}, fold {fold + 1}/{folds} done ({time.perf_counter() - start:.0f} s)")
        for key, parts in per_fold.items():
            metrics[key].append(np.concatenate(parts))
        for key, parts in per_fold_unmasked.items():
            unmasked[key].append(np.concatenate(parts))
    return IspResult(camera=real.name, rows=tuple(rows), seeds=tuple(seeds), folds=folds, n=n, size=size,
                     metrics=metrics, images=len(real.images), seconds=time.perf_counter() - start,
                     notes=list(dict.fromkeys(sets.notes)), skipped=list(skipped), examples=examples,
                     training=dataclasses.asdict(training), unmasked=unmasked)
