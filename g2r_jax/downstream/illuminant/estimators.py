"""Learned illuminant estimators for the downstream experiment: train on thumbnails, predict lights.

All three take thumbnails `images` (N, H, W, 3) float32 linear camera RGB (saturated pixels zeroed,
each image scaled to a maximum of 1; the project's are 64 x 64, see `thumbnails`) and their
illuminants (N, 3) of any scale, and return a predictor `predict(images) -> (M, 3)` of unit-norm
camera-RGB estimates.

- `cnn`: the paper's estimator. Graphics2RAW (Seo et al. ICCV 2023, supplement S1.2) uses the
  network of H. Gong, "Convolutional Mean: A Simple Convolutional Neural Network for Illuminant
  Estimation", BMVC 2019, as re-implemented in the paper's released code (SamsungLabs/graphics2raw,
  model_archs/cnn.py): conv 3x3 (3 -> 7) + 2x2 max-pool + ReLU, conv 3x3 (7 -> 14) + 2x2 max-pool +
  ReLU, conv 1x1 (14 -> 3) + ReLU, global mean over locations: 1,137 parameters. The architecture
  is theirs, written here in JAX; the training is scaled to our budget (see `cnn_config`): the
  thumbnails 2x2-binned to 32 x 32, random 16 x 16 patches with flips (the paper: 64 x 64
  patches of images downsampled 4x, about a twentieth of the frame, like ours), Adam (optax, through
  the one training base `g2r_jax.downstream.base.training.fit`),
  angular loss (the release trains on the L1 distance to the green-normalised light), the best of
  several checkpoints by mean angular error on a validation split held out of the training set
  (the release: 2000 epochs, best validation L1 loss). Ours deviates in one more place: the last
  layer's biases start at 1 (see `cnn_init`).
- `moments`: corrected moments (G. Finlayson, "Corrected-moment illuminant estimation", ICCV 2013):
  grey-world, max-RGB, shades of grey p = 2, 4, 8 (Finlayson & Trezzi 2004) and grey-edge (van de
  Weijer et al. 2007) estimates, each unit-normalised, mapped to the light by least squares.
- `histogram`: ridge regression from a 2-D log-chroma histogram (the representation of J. Barron,
  "Convolutional Color Constancy", ICCV 2015, Sec. 3, with a linear map in place of his learned
  filter) to the illuminant's log-chroma.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.downstream.base.training import FitResult, LoopConfig, fit
from g2r_jax.measure import duplicate_groups

ESTIMATORS = ("cnn", "moments", "histogram")

Predictor = Callable[[np.ndarray], np.ndarray]

_DARK = 1e-4          # a pixel with any channel at or below this (of the image's max) carries no colour


# ---------------------------------------------------------------- input checks

def _check_images(images, who: str) -> np.ndarray:
    array = np.asarray(images, dtype=np.float32)
    if array.ndim != 4 or array.shape[-1] != 3:
        raise ValueError(f"{who}: images must be (N, H, W, 3) camera RGB, got shape {np.shape(images)}")
    if array.shape[0] == 0:
        raise ValueError(f"{who}: no images")
    if not np.isfinite(array).all():
        raise ValueError(f"{who}: image {int(np.argmax(~np.isfinite(array).reshape(len(array), -1).all(1)))} "
                         "has non-finite pixels")
    if (array < 0).any():
        raise ValueError(f"{who}: image {int(np.argmax((array < 0).reshape(len(array), -1).any(1)))} has negative "
                         "pixels; expected linear camera RGB with black subtracted and clipped at 0")
    return array


def _check_lights(illuminants, count: int, who: str) -> np.ndarray:
    lights = np.asarray(illuminants, dtype=np.float64)
    if lights.shape != (count, 3):
        raise ValueError(f"{who}: illuminants must be ({count}, 3), one per image, got shape {lights.shape}")
    if not np.isfinite(lights).all() or (lights <= 0).any():
        row = int(np.argmax(~(np.isfinite(lights) & (lights > 0)).all(1)))
        raise ValueError(f"{who}: illuminant {row} is {lights[row]}; every channel must be finite and positive")
    return lights / np.linalg.norm(lights, axis=1, keepdims=True)


def _unit_rows(rgb: np.ndarray) -> np.ndarray:
    """Estimates -> unit-norm rows, each channel floored at 1e-6 of the row's size (a light is positive)."""
    rgb = np.asarray(rgb, np.float64)
    scale = np.maximum(np.abs(rgb).max(axis=1, keepdims=True), 1e-12)
    rgb = np.maximum(rgb, 1e-6 * scale)
    return (rgb / np.linalg.norm(rgb, axis=1, keepdims=True)).astype(np.float32)


# ---------------------------------------------------------------- corrected moments

def moment_features(images) -> np.ndarray:
    """(N, H, W, 3) -> (N, 18): six unit-norm RGB estimates per image (Finlayson 2013's inputs).

    Grey-world, max-RGB and shades of grey (Minkowski p = 2, 4, 8) over the pixels with every
    channel above `_DARK` (zeroed saturated pixels excluded); grey-edge: the mean per-channel
    gradient magnitude (forward differences) over 2 x 2 neighbourhoods of valid pixels. An image
    with no valid pixel (or no valid edge) gives the achromatic direction for that estimate.
    """
    x = np.ascontiguousarray(np.asarray(images, np.float32).transpose(0, 3, 1, 2))   # channel planes: fast sums
    n = len(x)
    valid = (x > _DARK).all(1, keepdims=True)                            # (N, 1, H, W)
    planes = np.where(valid, x, 0.0).reshape(n, 3, -1)                   # invalid pixels weigh nothing
    count = np.maximum(valid.reshape(n, -1).sum(1), 1)[:, None].astype(np.float32)
    squared = planes * planes
    fourth = squared * squared
    estimates = [planes.sum(-1) / count, planes.max(-1), np.sqrt(squared.sum(-1) / count),
                 (fourth.sum(-1) / count) ** 0.25, ((fourth * fourth).sum(-1) / count) ** 0.125]
    dx = x[:, :, :-1, 1:] - x[:, :, :-1, :-1]
    dy = x[:, :, 1:, :-1] - x[:, :, :-1, :-1]
    edge_ok = valid[:, :, :-1, :-1] & valid[:, :, :-1, 1:] & valid[:, :, 1:, :-1]
    magnitude = np.where(edge_ok, np.sqrt(dx * dx + dy * dy), 0.0).reshape(n, 3, -1)
    estimates.append(magnitude.sum(-1) / np.maximum(edge_ok.reshape(n, -1).sum(1), 1)[:, None])
    features = []
    for e in estimates:
        norm = np.linalg.norm(e, axis=1, keepdims=True)
        features.append(np.where(norm > 1e-12, e / np.maximum(norm, 1e-12), 1 / np.sqrt(3)))
    return np.concatenate(features, axis=1).astype(np.float64)


def _sample_weights(weights, count: int, who: str) -> np.ndarray:
    """Per-image weights of a least-squares fit, scaled to sum to `count` (1 each without)."""
    if weights is None:
        return np.ones(count)
    weights = np.asarray(weights, np.float64)
    if weights.shape != (count,) or not np.all(np.isfinite(weights)) or np.any(weights < 0) or weights.sum() <= 0:
        raise ValueError(f"{who}: weights must be ({count},) non-negative, not all 0")
    return weights * (count / weights.sum())


def train_moments(images, illuminants, *, seed: int = 0, ridge: float = 1e-6, weights=None) -> Predictor:
    """Corrected moments (Finlayson, ICCV 2013, Sec. 3): light = [features, 1] @ C, C by least squares.

    `ridge` (times the number of images) keeps C defined when features are collinear; `weights`
    (N,): each image's weight in the least squares (augmentation's mixed sets), equal without;
    `seed` is unused (closed form), accepted for a common signature.
    """
    x = _check_images(images, "moments")
    target = _check_lights(illuminants, len(x), "moments")
    w = _sample_weights(weights, len(x), "moments")[:, None]
    design = np.c_[moment_features(x), np.ones(len(x))]
    gram = design.T @ (w * design) + ridge * len(x) * np.eye(design.shape[1])
    correction = np.linalg.solve(gram, design.T @ (w * target))

    def predict(test_images) -> np.ndarray:
        t = _check_images(test_images, "moments predictor")
        return _unit_rows(np.c_[moment_features(t), np.ones(len(t))] @ correction)

    return predict


# ---------------------------------------------------------------- log-chroma histogram

@dataclasses.dataclass(frozen=True)
class HistogramGrid:
    """The log-chroma grid u = log(g / r), v = log(g / b): `bins` per axis over centre +- half_width."""
    centre: tuple
    half_width: float = 1.6
    bins: int = 32


def log_chroma(rgb: np.ndarray) -> np.ndarray:
    """(..., 3) positive RGB -> (..., 2) (log(g / r), log(g / b)) (Barron 2015, Eq. 2)."""
    rgb = np.asarray(rgb, np.float64)
    return np.stack([np.log(rgb[..., 1] / rgb[..., 0]), np.log(rgb[..., 1] / rgb[..., 2])], -1)


@dataclasses.dataclass(frozen=True)
class ChromaPixels:
    """Images as the histogram estimator reads them, whatever its grid: per pixel the log
    chromaticities u = log(g / r), v = log(g / b) (float32), the brightness r + g + b, and
    whether every channel is above `_DARK`; each (N, H * W). Indexing and `concatenate` work as on
    the images, so a set's pixels are decoded once for many trainings (the recipe's
    cross-validation of `downstream.illuminant.augmentation`); features from them equal the images'
    to the bit."""
    u: np.ndarray
    v: np.ndarray
    brightness: np.ndarray
    valid: np.ndarray

    def __len__(self) -> int:
        return len(self.u)

    def __array__(self, dtype=None, copy=None):
        raise TypeError("ChromaPixels are an image set's decoded pixels, not an image array")

    def __getitem__(self, index) -> "ChromaPixels":
        return ChromaPixels(self.u[index], self.v[index], self.brightness[index], self.valid[index])

    @staticmethod
    def concatenate(parts) -> "ChromaPixels":
        return ChromaPixels(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("u", "v", "brightness", "valid")))


def chroma_pixels(images) -> ChromaPixels:
    """(N, H, W, 3) camera RGB (checked as the estimators check them) -> their `ChromaPixels`."""
    return _chroma_pixels(_check_images(images, "histogram"))


def decoded_for(kind: str, images):
    """`images` in the form estimator `kind` reads fastest when one set trains it many times (the
    recipe choice's cross-validation): the histogram's `ChromaPixels`, decoded once; the images
    themselves for the others."""
    return chroma_pixels(images) if kind == "histogram" else images


def joined(parts):
    """Image sets, or `ChromaPixels`, one after the other (the mixed recipes' training sets)."""
    if isinstance(parts[0], ChromaPixels):
        return ChromaPixels.concatenate(parts)
    return np.concatenate([np.asarray(part, np.float32) for part in parts])


def _chroma_pixels(images) -> ChromaPixels:
    x = np.ascontiguousarray(np.asarray(images, np.float32).transpose(0, 3, 1, 2)).reshape(len(images), 3, -1)
    valid = (x > _DARK).all(1)                                           # (N, H * W)
    logs = np.log(np.where(valid[:, None], x, 1.0))
    return ChromaPixels(logs[:, 1] - logs[:, 0], logs[:, 1] - logs[:, 2], x.sum(1), valid)


def histogram_features(images, grid: HistogramGrid) -> np.ndarray:
    """(N, H, W, 3) images or their `ChromaPixels` -> (N, bins * bins): each image's log-chroma
    histogram, pixels weighted by their brightness (r + g + b), normalised to sum 1, square-rooted
    (so a few large uniform regions do not dominate). Pixels with a channel at or below `_DARK` or
    off the grid are left out."""
    pixels = images if isinstance(images, ChromaPixels) else _chroma_pixels(images)
    n = len(pixels)
    low = np.asarray(grid.centre, np.float32) - grid.half_width
    cell = 2 * grid.half_width / grid.bins
    u = np.floor((pixels.u - low[0]) / cell).astype(np.int32)
    v = np.floor((pixels.v - low[1]) / cell).astype(np.int32)
    inside = pixels.valid & (u >= 0) & (u < grid.bins) & (v >= 0) & (v < grid.bins)
    flat = np.where(inside, u * grid.bins + v, 0) + (np.arange(n) * grid.bins ** 2)[:, None]
    weight = np.where(inside, pixels.brightness, 0.0)
    counts = np.bincount(flat.ravel(), weights=weight.ravel(), minlength=n * grid.bins ** 2).reshape(n, -1)
    counts /= np.maximum(counts.sum(1, keepdims=True), 1e-12)
    return np.sqrt(counts)


def train_histogram(images, illuminants, *, seed: int = 0, ridge: float = 1e-2,
                    half_width: float = 1.6, bins: int = 32, weights=None) -> Predictor:
    """Ridge regression histogram -> illuminant log-chroma (linear, in the spirit of Barron 2015).

    The grid is centred on the training lights' mean log-chroma (pixels are surface chroma plus
    light chroma, Barron Eq. 3, so the lights fix where the mass lies); `images` (N, H, W, 3) or
    their `ChromaPixels` (its predictor takes either too); `ridge` times the number of
    images is the Tikhonov weight on centred features; `weights` (N,) each image's weight in the
    means and the least squares (equal without). `seed` is unused (closed form).
    """
    x = images if isinstance(images, ChromaPixels) else _check_images(images, "histogram")
    lights = _check_lights(illuminants, len(x), "histogram")
    w = _sample_weights(weights, len(x), "histogram")[:, None]
    target = log_chroma(lights)
    mean_target = (w * target).sum(0) / w.sum()
    grid = HistogramGrid(centre=tuple(float(c) for c in mean_target), half_width=half_width, bins=bins)
    features = histogram_features(x, grid)
    mean_feature = (w * features).sum(0) / w.sum()
    centred = features - mean_feature
    gram = centred.T @ (w * centred) + ridge * len(x) * np.eye(centred.shape[1])
    weights = np.linalg.solve(gram, centred.T @ (w * (target - mean_target)))

    def predict(test_images) -> np.ndarray:
        t = test_images if isinstance(test_images, ChromaPixels) else _check_images(test_images, "histogram predictor")
        uv = (histogram_features(t, grid) - mean_feature) @ weights + mean_target
        return _unit_rows(np.stack([np.exp(-uv[:, 0]), np.ones(len(uv)), np.exp(-uv[:, 1])], 1))

    return predict


# ---------------------------------------------------------------- the CNN (Gong 2019, as in Graphics2RAW)

@dataclasses.dataclass(frozen=True)
class CnnConfig:
    """Training of the CNN, chosen for about a second of CPU per model (see
    benchmarks/downstream_estimators_speed.py for the measurements that chose it)."""
    binning: int = 2            # thumbnails averaged over binning x binning pixels first
    patch: int = 16             # side of the random training patches (after binning)
    batch: int = 32
    checkpoints: int = 8        # validation evaluations; the best one is kept
    steps_per_checkpoint: int = 40
    learning_rate: float = 1e-2
    validation_fraction: float = 1 / 6     # the paper's 25 of 150 training images
    max_validation: int = 64    # images the validation error is measured on (a random subset)
    filters: int = 7            # Gong's width: 7 then 14 channels


class SameConv(eqx.Module):
    """A 'same' convolution (HWIO kernel of odd size, NHWC input) computed as one matrix product
    over shifted copies: on CPU, inside the training loop, about 3x faster than lax.conv for
    these few channels (benchmarks/downstream_estimators_speed.py)."""

    weight: jax.Array
    bias: jax.Array

    def __call__(self, x):
        size, inputs, outputs = self.weight.shape[0], self.weight.shape[2], self.weight.shape[3]
        if size == 1:
            return x @ self.weight[0, 0] + self.bias
        _, h, w, _ = x.shape
        r = size // 2
        padded = jnp.pad(x, ((0, 0), (r, r), (r, r), (0, 0)))
        columns = jnp.concatenate([padded[:, i:i + h, j:j + w] for i in range(size) for j in range(size)], -1)
        return columns @ self.weight.reshape(size * size * inputs, outputs) + self.bias


def _max_pool2(x):
    b, h, w, c = x.shape
    return x[:, : h // 2 * 2, : w // 2 * 2].reshape(b, h // 2, 2, w // 2, 2, c).max((2, 4))


class ConvolutionalMean(eqx.Module):
    """Gong's network (BMVC 2019, as in Graphics2RAW's model_archs/cnn.py): conv 3x3 + 2x2
    max-pool + ReLU twice, conv 1x1 + ReLU, mean over locations. (B, H, W, 3) -> (B, 3)."""

    conv1: SameConv
    conv2: SameConv
    conv3: SameConv

    def local_estimates(self, x):
        """(B, H, W, 3) -> (B, H/4, W/4, 3): the per-location estimates before the mean."""
        y = jax.nn.relu(_max_pool2(self.conv1(x)))
        y = jax.nn.relu(_max_pool2(self.conv2(y)))
        return jax.nn.relu(self.conv3(y))

    def __call__(self, x):
        return self.local_estimates(x).mean((1, 2))


def cnn_init(seed: int, filters: int = 7) -> ConvolutionalMean:
    """Gong's network initialised as PyTorch's default (uniform +- 1/sqrt(fan_in), numpy's
    generator for `seed`), except the last layer's biases, set to 1 so that no output channel
    starts dead behind its ReLU (a channel negative at every location never receives a gradient
    again; with the default biases that happened on real data)."""
    rng = np.random.default_rng([seed, 1137])
    layers = []
    for shape in ((3, 3, 3, filters), (3, 3, filters, 2 * filters), (1, 1, 2 * filters, 3)):
        bound = 1.0 / np.sqrt(np.prod(shape[:3]))
        layers.append(SameConv(jnp.asarray(rng.uniform(-bound, bound, shape).astype(np.float32)),
                               jnp.asarray(rng.uniform(-bound, bound, shape[3]).astype(np.float32))))
    layers[2] = SameConv(layers[2].weight, jnp.ones(3, jnp.float32))
    return ConvolutionalMean(*layers)


def count_parameters(model) -> int:
    return int(sum(np.size(leaf) for leaf in jax.tree_util.tree_leaves(eqx.filter(model, eqx.is_array))))


def cnn_apply(model, x):
    """(B, H, W, 3) -> (B, 3): Gong's convolutional mean, the average of the local estimates."""
    return model(x)


def _angular_loss_degrees(estimate, truth):
    """Mean angle (degrees) between rows; differentiable at zero angle (atan2 form, eps-guarded)."""
    e = estimate / jnp.sqrt(jnp.sum(estimate ** 2, -1, keepdims=True) + 1e-12)
    t = truth / jnp.sqrt(jnp.sum(truth ** 2, -1, keepdims=True) + 1e-12)
    cross = jnp.cross(e, t)
    sine = jnp.sqrt(jnp.sum(cross ** 2, -1) + 1e-12)
    return jnp.degrees(jnp.arctan2(sine, jnp.sum(e * t, -1)))


def _bin(images: np.ndarray, factor: int) -> np.ndarray:
    """Average factor x factor blocks and rescale each image to a maximum of 1."""
    if factor == 1:
        return images
    n, h, w, _ = images.shape
    binned = images[:, : h // factor * factor, : w // factor * factor].reshape(
        n, h // factor, factor, w // factor, factor, 3).mean((2, 4))
    peak = binned.reshape(n, -1).max(1)
    return binned / np.where(peak > 0, peak, 1.0)[:, None, None, None]


def _bucket(count: int, smallest: int) -> int:
    """Array capacity for `count` rows: the next power of two (at least `smallest`), so that a few
    compiled programs serve every set size."""
    return max(smallest, 1 << int(np.ceil(np.log2(max(count, 1)))))


def _pad(array: np.ndarray, rows: int) -> np.ndarray:
    return np.concatenate([array, np.zeros((rows - len(array),) + array.shape[1:], array.dtype)])


def _split(images: np.ndarray, fraction: float, limit: int, rng: np.random.Generator):
    """Training / validation indices: a random `fraction` of the distinct images (at most `limit`
    of them, at least one) held out; identical images (a set repeated to size; found by
    `measure.duplicate_groups`, numbered by digest as the release before it drew them) stay on one side."""
    groups = duplicate_groups(images, order="hash")
    distinct = np.unique(groups)
    if len(distinct) < 2:
        raise ValueError("cnn: the training set needs at least two distinct images (one is held out "
                         "for validation)")
    held = rng.permutation(distinct)[: int(np.clip(round(fraction * len(distinct)), 1, min(limit, len(distinct) - 1)))]
    is_val = np.isin(groups, held)
    val = np.flatnonzero(is_val)
    if len(val) > limit:
        val = np.sort(rng.choice(val, limit, replace=False))
    return np.flatnonzero(~is_val), val


def _random_crops(key, patch: int, batch: int, train_x, train_y, n_train, probabilities=None):
    """`batch` random patch x patch crops of the first `n_train` images (drawn uniformly, or by
    `probabilities` over the padded rows), each flipped at random left-right and up-down, with
    their lights."""
    height, width = train_x.shape[1:3]
    k_index, k_y, k_x, k_flip = jax.random.split(key, 4)
    if probabilities is None:
        index = jax.random.randint(k_index, (batch,), 0, n_train)
    else:
        index = jax.random.choice(k_index, train_x.shape[0], (batch,), p=probabilities)
    top = jax.random.randint(k_y, (batch,), 0, height - patch + 1)
    left = jax.random.randint(k_x, (batch,), 0, width - patch + 1)
    crops = jax.vmap(lambda i, t, l: jax.lax.dynamic_slice(train_x[i], (t, l, 0), (patch, patch, 3)))(index, top, left)
    flips = jax.random.bernoulli(k_flip, 0.5, (2, batch))[..., None, None, None]
    crops = jnp.where(flips[0], crops[:, :, ::-1], crops)
    crops = jnp.where(flips[1], crops[:, ::-1], crops)
    return crops, train_y[index]


@functools.lru_cache(maxsize=None)
def _cnn_step_loss(patch: int, batch: int):
    """The training loss of one step for `fit`: the mean angular error on `batch` random crops of
    patch x patch (`data`: the padded training images, lights and their count). One function per
    (patch, batch), so that compiled programs are reused."""

    def step_loss(model, key, data):
        train_x, train_y, n_train = data
        crops, lights = _random_crops(key, patch, batch, train_x, train_y, n_train)
        return _angular_loss_degrees(model(crops), lights).mean()

    return step_loss


@functools.lru_cache(maxsize=None)
def _cnn_drawn_step_loss(patch: int, batch: int):
    """`_cnn_step_loss` with the crops' images drawn by per-image probabilities (`data`: the padded
    training images, lights, their count and the probabilities): augmentation's mixed batches."""

    def step_loss(model, key, data):
        train_x, train_y, n_train, probabilities = data
        crops, lights = _random_crops(key, patch, batch, train_x, train_y, n_train, probabilities)
        return _angular_loss_degrees(model(crops), lights).mean()

    return step_loss


def _cnn_validation_error(model, validation):
    val_x, val_y, val_w = validation
    errors = _angular_loss_degrees(model(val_x), val_y)
    return jnp.sum(jnp.where(val_w > 0, errors, 0.0)) / jnp.sum(val_w)


def _loop_config(config: "CnnConfig") -> LoopConfig:
    return LoopConfig(rounds=config.checkpoints, steps_per_round=config.steps_per_checkpoint,
                      learning_rate=config.learning_rate)


@eqx.filter_jit
def _apply_jit(model, x):
    return model(x)


@dataclasses.dataclass
class CnnPredictor:
    """A trained CNN: `predict(images)` (also callable) gives unit-norm estimates; `params` (the
    equinox module), the validation error of the kept checkpoint and the curve (validation error,
    mean training loss per checkpoint) are kept for reports."""
    params: ConvolutionalMean
    config: "CnnConfig"
    validation_error: float
    curve: tuple

    def __call__(self, images) -> np.ndarray:
        x = _bin(_check_images(images, "cnn predictor"), self.config.binning)
        out = [np.asarray(_apply_jit(self.params, jnp.asarray(x[s:s + 512]))) for s in range(0, len(x), 512)]
        return _unit_rows(np.concatenate(out))

    predict = __call__


def _prepare(images, illuminants, seed: int, config: "CnnConfig", *, sampling=None, validation_from=None):
    """(model, round keys (checkpoints, steps, 2), data, validation) of one training; with
    `sampling` (N,) the crops' images are drawn by these weights (data then carries their
    probabilities), with `validation_from` (N,) bool the validation images come from those only."""
    x = _check_images(images, "cnn")
    lights = _check_lights(illuminants, len(x), "cnn").astype(np.float32)
    binned = _bin(x, config.binning)
    if min(binned.shape[1:3]) < config.patch:
        raise ValueError(f"cnn: images of {x.shape[1]} x {x.shape[2]} binned {config.binning}x are smaller "
                         f"than the {config.patch}-pixel training patch")
    rng = np.random.default_rng(seed)
    pool = np.arange(len(x)) if validation_from is None else np.flatnonzero(validation_from)
    val = pool[_split(x[pool], config.validation_fraction, config.max_validation, rng)[1]]
    train = np.setdiff1d(np.arange(len(x)), val)
    capacity = _bucket(len(train), 256)
    val_w = np.zeros(config.max_validation, np.float32)
    val_w[: len(val)] = 1.0
    data = (_pad(binned[train], capacity), _pad(lights[train], capacity), np.int32(len(train)))
    if sampling is not None:
        drawn = _pad(np.asarray(sampling, np.float32)[train], capacity)
        data = data + (drawn / drawn.sum(),)
    validation = (_pad(binned[val], config.max_validation), _pad(lights[val], config.max_validation), val_w)
    keys = jax.vmap(lambda k: jax.random.split(k, config.steps_per_checkpoint))(
        jax.random.split(jax.random.PRNGKey(seed), config.checkpoints))
    return cnn_init(seed, config.filters), np.asarray(keys), data, validation


def _predictor(fitted: FitResult, config, member=None) -> CnnPredictor:
    take = (lambda a: np.asarray(a)) if member is None else (lambda a: np.asarray(a[member]))
    pick = (lambda a: a) if member is None else (lambda a: a[:, member])
    curve, losses = pick(fitted.curve), pick(fitted.losses)
    return CnnPredictor(params=jax.tree_util.tree_map(take, fitted.model), config=config,
                        validation_error=float(np.min(curve)), curve=(curve, losses))


def train_cnn(images, illuminants, *, seed: int = 0, config: CnnConfig = CnnConfig(), init=None,
              sampling=None, validation_from=None) -> CnnPredictor:
    """Train Gong's convolutional-mean CNN (see the module docstring) with `training.fit`: Adam at
    a constant rate, the best of `checkpoints` rounds by validation error; deterministic for a seed.

    For augmentation (`downstream.illuminant.augmentation`): `init` a `ConvolutionalMean` to start from (fine-
    tuning; default `cnn_init(seed)`); `sampling` (N,) non-negative weights by which each step's
    crops draw their images (default: uniformly); `validation_from` (N,) bool: the images the
    checkpoints' validation split is drawn from (default: all)."""
    model, keys, data, validation = _prepare(images, illuminants, seed, config, sampling=sampling,
                                             validation_from=validation_from)
    step_loss = (_cnn_step_loss if sampling is None else _cnn_drawn_step_loss)(config.patch, config.batch)
    fitted = fit(model if init is None else init, step_loss, lambda r: keys[r], data, _loop_config(config),
                 validate=_cnn_validation_error, validation_data=validation)
    return _predictor(fitted, config)


def train_many_cnn(sets: Sequence[tuple], seeds: Sequence[int], *,
                   config: CnnConfig = CnnConfig()) -> list:
    """Several CNN trainings as one vmapped program (sets of one capacity are batched together).

    **Arguments:** `sets`: (images, illuminants) pairs; `seeds`: one per set. **Returns:** one
    `CnnPredictor` per set, equal to `train_cnn(images, illuminants, seed=seed)` up to float
    reassociation.
    """
    if len(sets) != len(seeds):
        raise ValueError(f"{len(sets)} training sets but {len(seeds)} seeds")
    prepared = [_prepare(images, lights, seed, config) for (images, lights), seed in zip(sets, seeds)]
    out = [None] * len(sets)
    for capacity in sorted({p[2][0].shape[0] for p in prepared}):
        members = [i for i, p in enumerate(prepared) if p[2][0].shape[0] == capacity]
        model, keys, data, validation = jax.tree_util.tree_map(lambda *leaves: np.stack(leaves),
                                                               *[prepared[i] for i in members])
        fitted = fit(jax.tree_util.tree_map(jnp.asarray, model), _cnn_step_loss(config.patch, config.batch), lambda r: keys[:, r], data,
                     _loop_config(config), validate=_cnn_validation_error, validation_data=validation, members=True)
        for j, i in enumerate(members):
            out[i] = _predictor(fitted, config, j)
    return out


# ---------------------------------------------------------------- the common entry

_TRAINERS = {"cnn": train_cnn, "moments": train_moments, "histogram": train_histogram}


def train_estimator(kind: str, images, illuminants, *, seed: int = 0, weights=None) -> Predictor:
    """Train estimator `kind` (one of `ESTIMATORS`) on thumbnails and their lights; deterministic
    for a seed. `weights` (N,): each image's share of the training (the closed forms' least
    squares; the CNN's crops are drawn by them). **Returns:** `predict(images) -> (M, 3)` unit-norm
    camera-RGB estimates."""
    if kind not in _TRAINERS:
        raise ValueError(f"unknown estimator {kind!r}; expected one of {', '.join(ESTIMATORS)}")
    if weights is None:
        return _TRAINERS[kind](images, illuminants, seed=seed)
    if kind == "cnn":
        return train_cnn(images, illuminants, seed=seed, sampling=weights)
    return _TRAINERS[kind](images, illuminants, seed=seed, weights=weights)


def train_many(kind: str, sets: Sequence[tuple], seeds: Sequence[int]) -> list:
    """`train_estimator` for several (images, illuminants) sets; the CNN's are trained together
    in one vmapped program (see benchmarks/downstream_estimators_speed.py for when that pays)."""
    if kind == "cnn":
        return train_many_cnn(sets, seeds)
    if len(sets) != len(seeds):
        raise ValueError(f"{len(sets)} training sets but {len(seeds)} seeds")
    return [train_estimator(kind, images, lights, seed=seed) for (images, lights), seed in zip(sets, seeds)]
