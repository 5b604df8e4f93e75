"""The neural-ISP task's network and measures: a small UNet (Ronneberger, Fischer, Brox, "U-Net",
MICCAI 2015) from packed RAW to display sRGB, trained with L1 loss on the one training base
(`g2r_jax.downstream.base.training.fit`: Adam, cosine decay to a tenth), and the per-image PSNR, SSIM
and CIEDE2000 of its outputs.

The UNet (`IspUNet`, NCHW / OIHW like the denoiser), on packed planes (B, 4, h, w):
- encoder: two 3x3 convolutions of `width` channels -> 2x2 average pooling -> two of 2 `width`
  -> pooling -> one of 4 `width`;
- global branch: the spatial mean of those features and the log means of the four input planes
  (their grey-world colour, Buchsbaum 1980) through one dense layer, giving a feature bias added
  back at the bottleneck and four per-image gains (exp(1.5 tanh(.)), within 0.22-4.5): the white
  balance is a property of the whole image, which a few 3x3 convolutions do not see;
- decoder: one more 3x3 -> nearest upsampling, concatenation with the encoder's features of the
  same scale and two 3x3 convolutions, twice -> a 1x1 convolution to 12 channels;
- a linear colour path beside it: the input planes times the gains, clipped at 1 (a developer's
  white balance clips there too), through one 3x3 convolution to 12 channels;
- output: the two 12-channel maps summed as linear light, a depth-to-space (pixel shuffle: Shi et
  al., CVPR 2016) to (B, 3, 2h, 2w), the full resolution of the mosaic, and the fixed sRGB curve
  (IEC 61966-2-1; its linear toe continued below 0). ReLU between layers; the outputs are clipped
  to [0, 1] when measured.
The linear path and the fixed output curve are what a developer does (gains, demosaic and colour
matrix are linear; the curve is known); with them a small UNet learns an ISP in hundreds of steps.
Measured while building it (NUS Canon 600D thumbnails mosaicked one site per pixel, the fit to
the pairs trained on): a plain UNet of width 8 with sRGB out reached 18.0 dB after 1,000 steps of
16 (Adam 5e-3); one linear 3x3 convolution with the fixed curve 24.3 dB (3,000 full-batch steps);
an early form of this UNet (linear path and curve, no grey-world input) 27.1 dB after 1,000
steps of 16 (Adam 1e-2).
Stability (held-out synthetic pairs, 5 seeds): He-scaled colour path and last layer gave ΔE2000
4.50-5.91 over the seeds, a tenth of that scale 3.96-4.52; with the sRGB curve clamped at 0 one
run in five then ended at 18 dB (outputs below 0 get no gradient); with the toe continued below
0 the five seeds span 28.5-29.5 dB (ΔE2000 4.72-4.95).

Several trainings can run as one vmapped program (`fit(..., members=True)`); on a CPU that is
slower (XLA turns the vmapped convolutions into grouped ones: an early form of this UNet, width
8, ran 676 ms per step for 7 models against 7 x 17 ms one at a time, 2 cores), so
`IspTraining.together` defaults to vmapping on accelerators only.
"""

from __future__ import annotations

import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.downstream.base.training import LoopConfig, fit


@dataclasses.dataclass(frozen=True)
class IspTraining:
    """One ISP training: `steps` Adam steps (whole rounds of `steps_per_round`) of `batch` whole
    images, peak learning rate `learning_rate` decayed (cosine) to a tenth; the UNet's `width`;
    `validation`: the share of each training set held out (seeded) to keep the round whose mean
    L1 error on it is lowest (none below 10 images or at 0: the last round is kept), as the
    paper's trainings keep the best checkpoint on a validation split of their own training data;
    `together`: train a fold's rows as one vmapped program (None: on accelerators, not on a CPU)."""

    width: int = 8
    batch: int = 8
    steps: int = 600
    steps_per_round: int = 100
    learning_rate: float = 1e-2
    validation: float = 0.1
    together: bool | None = None


def _conv(x, kernel, bias):
    pad = kernel.shape[-1] // 2
    y = jax.lax.conv_general_dilated(x, kernel, (1, 1), ((pad, pad), (pad, pad)),
                                     dimension_numbers=("NCHW", "OIHW", "NCHW"))
    return y + bias[None, :, None, None]


def _down(x):
    b, c, h, w = x.shape
    return x.reshape(b, c, h // 2, 2, w // 2, 2).mean((3, 5))


def _up(x):
    return jnp.repeat(jnp.repeat(x, 2, axis=2), 2, axis=3)


def _layer_shapes(width: int) -> list:
    """(out, in, kernel side) of the UNet's convolutions, in the order `IspUNet.__call__` uses them;
    the last is the linear colour path (packed planes -> 12 = 3 colours x 4 sub-pixels)."""
    c = width
    return [(c, 4, 3), (c, c, 3), (2 * c, c, 3), (2 * c, 2 * c, 3), (4 * c, 2 * c, 3), (4 * c, 4 * c, 3),
            (2 * c, 6 * c, 3), (2 * c, 2 * c, 3), (c, 3 * c, 3), (c, c, 3), (12, c, 1), (12, 4, 3)]


def _depth_to_space(y):
    """(B, 12, h, w) -> (B, 3, 2h, 2w): channel 4 c + 2 i + j is colour c at sub-pixel (i, j)."""
    n, _, h, w = y.shape
    return y.reshape(n, 3, 2, 2, h, w).transpose(0, 1, 4, 2, 5, 3).reshape(n, 3, 2 * h, 2 * w)


def _srgb_encode(linear):
    """IEC 61966-2-1 sRGB coding of linear values, its linear toe continued below 0 (so that a
    negative output still has a gradient; outputs are clipped to [0, 1] when measured)."""
    power = 1.055 * jnp.power(jnp.maximum(linear, 0.0031308), 1 / 2.4) - 0.055
    return jnp.where(linear <= 0.0031308, 12.92 * linear, power)


class IspUNet(eqx.Module):
    """See the module docstring. `kernels` OIHW, `biases`; the global branch's dense layers
    (`global_weight` (4w, 4w + 4), `global_bias`): a feature bias for the bottleneck and the
    log gains of the four planes."""

    kernels: tuple
    biases: tuple
    global_weight: jax.Array
    global_bias: jax.Array

    def __call__(self, packed):
        k, b, relu = self.kernels, self.biases, jax.nn.relu
        block = lambda x, i: relu(_conv(relu(_conv(x, k[i], b[i])), k[i + 1], b[i + 1]))
        e0 = block(packed, 0)
        e1 = block(_down(e0), 2)
        e2 = relu(_conv(_down(e1), k[4], b[4]))
        grey = jnp.log(jnp.mean(packed, axis=(2, 3)) + 1e-3)           # (B, 4): the planes' means (grey world)
        pooled = jnp.concatenate([jnp.mean(e2, axis=(2, 3)), grey - grey[:, 1:3].mean(1, keepdims=True)], axis=1)
        context = pooled @ self.global_weight + self.global_bias
        features, log_gains = context[:, :-4], context[:, -4:]
        e2 = relu(_conv(e2 + features[:, :, None, None], k[5], b[5]))
        d1 = block(jnp.concatenate([_up(e2), e1], axis=1), 6)
        d0 = block(jnp.concatenate([_up(d1), e0], axis=1), 8)
        balanced = jnp.minimum(packed * jnp.exp(1.5 * jnp.tanh(log_gains))[:, :, None, None], 1.0)   # gains, then clipping
        linear = _conv(balanced, k[11], b[11]) + _conv(d0, k[10], b[10])      # (B, 12, h, w)
        return _srgb_encode(_depth_to_space(linear))


def init_unet(seed: int, width: int = 8) -> IspUNet:
    """He-initialised kernels (He et al., ICCV 2015; drawn by numpy from `seed`: no compiled
    program per layer shape), zero biases, the global branch at zero (it starts as a plain UNet
    with unit gains); the UNet's last layer at a tenth, so that the linear colour path carries the
    start. **Arguments:** `seed` an int; `width` channels at full resolution. **Returns:** an
    `IspUNet`."""
    rng = np.random.default_rng([int(seed), 4242])
    kernels, biases = [], []
    for i, (n_out, n_in, side) in enumerate(_layer_shapes(width)):
        scale = np.sqrt(2.0 / (n_in * side * side)) * (0.1 if i >= 10 else 1.0)
        kernels.append(jnp.asarray(scale * rng.standard_normal((n_out, n_in, side, side)), jnp.float32))
        biases.append(jnp.zeros(n_out, jnp.float32))
    return IspUNet(tuple(kernels), tuple(biases), jnp.zeros((4 * width + 4, 4 * width + 4), jnp.float32),
                   jnp.zeros(4 * width + 4, jnp.float32))


def _masked_l1(predicted, targets, weights, axis=None):
    """Mean absolute error over the pixels of weight 1 (weights (N, 1, H, W), 0 or 1)."""
    total = jnp.sum(jnp.abs(predicted - targets) * weights, axis=axis)
    return total / jnp.maximum(predicted.shape[1] * jnp.sum(weights, axis=axis), 1.0)


def _step_loss(model, indices, data):
    """L1 between the UNet's output and the targets of the step's images (`indices` into data),
    over the pixels the data holds (weights 1; the real thumbnails' masked pixels 0)."""
    packed, targets, weights = data
    return _masked_l1(model(packed[indices]), targets[indices], weights[indices])


def _channels_first(packed, targets, mask=None):
    """(packed, targets, weights) channels first; weights (N, 1, H, W) float32 from the (N, H, W)
    `mask` (True: trained on), 1 everywhere without one."""
    targets = np.ascontiguousarray(np.asarray(targets, np.float32).transpose(0, 3, 1, 2))
    weights = (np.ones((len(targets), 1) + targets.shape[2:], np.float32) if mask is None
               else np.asarray(mask, np.float32)[:, None])
    return np.ascontiguousarray(np.asarray(packed, np.float32).transpose(0, 3, 1, 2)), targets, weights


def _config(training: IspTraining, scan: bool) -> LoopConfig:
    rounds = max(1, -(-int(training.steps) // training.steps_per_round))
    return LoopConfig(rounds=rounds, steps_per_round=training.steps_per_round, learning_rate=training.learning_rate,
                      final_fraction=0.1, scan=scan)


def _index_rounds(counts, seeds, training: IspTraining):
    """round_inputs(r): (members, steps, batch) indices, member m's drawn from range(counts[m])
    by its seed (round r from [seed, r])."""
    def round_inputs(r):
        return np.stack([np.random.default_rng([int(s), 7, r]).integers(0, c, (training.steps_per_round, training.batch))
                         for c, s in zip(counts, seeds)]).astype(np.int32)
    return round_inputs


def _together(training: IspTraining) -> bool:
    return training.together if training.together is not None else jax.default_backend() != "cpu"


def _validation_error(model, validation):
    """Mean masked L1 error of the model on the held-out pairs (pairs weighted 0 are padding)."""
    packed, targets, weights, pair_weights = validation
    errors = _masked_l1(model(packed), targets, weights, axis=(1, 2, 3))
    return jnp.sum(errors * pair_weights) / jnp.maximum(jnp.sum(pair_weights), 1.0)


def _split(arrays, seed: int, share: float):
    """(training arrays, held-out arrays): `share` of the pairs held out by a seeded permutation
    (none when fewer than 10 pairs or `share` is 0)."""
    count = len(arrays[0])
    held = int(round(share * count)) if count >= 10 else 0
    if held < 1:
        return arrays, None
    order = np.random.default_rng([int(seed), 11]).permutation(count)
    keep, out = np.sort(order[held:]), np.sort(order[:held])
    return tuple(a[keep] for a in arrays), tuple(a[out] for a in arrays)


def _padded_validation(held, capacity: int):
    """(packed, targets, weights, pair weights) of `capacity` pairs: the held-out ones, then
    copies weighted 0."""
    pair_weights = np.r_[np.ones(len(held[0])), np.zeros(capacity - len(held[0]))].astype(np.float32)
    pad = lambda a: np.concatenate([a, np.repeat(a[:1], capacity - len(a), axis=0)])
    return (*(pad(a) for a in held), pair_weights)


def train_many(sets, seeds, training: IspTraining = IspTraining(), initial=None) -> list:
    """One UNet per training set, each from its seed's initialisation, batches and held-out share
    (deterministic).

    **Arguments:** `sets`: (packed (N, h, w, 4), targets (N, 2h, 2w, 3)[, mask (N, 2h, 2w)])
    arrays, all of one image size (a mask's False pixels are out of the loss); `seeds`: one per set; `training`: an `IspTraining`. With `together` the sets
    are padded to one length and trained as one vmapped program; `initial`: one trained
    `IspUNet` per set to start from (fine-tuning: the same schedule, from its weights) instead
    of the seed's initialisation.
    **Returns:** one trained `IspUNet` per set.
    """
    if len(sets) != len(seeds) or (initial is not None and len(initial) != len(sets)):
        raise ValueError(f"{len(sets)} training sets but {len(seeds)} seeds"
                         + ("" if initial is None else f" and {len(initial)} initial networks"))
    if min((len(arrays[0]) for arrays in sets), default=1) < 1:
        raise ValueError("an ISP training set is empty")
    splits = [_split(_channels_first(*arrays), s, training.validation) for arrays, s in zip(sets, seeds)]
    prepared, held = [a for a, _ in splits], [b for _, b in splits]
    counts = [len(arrays[0]) for arrays in prepared]
    models = list(initial) if initial is not None else [init_unet(int(s), training.width) for s in seeds]
    validate = None if any(h is None for h in held) else _validation_error
    if _together(training) and len(sets) > 1:
        capacity = max(counts)
        pad = lambda a: np.concatenate([a, np.repeat(a[:1], capacity - len(a), axis=0)])
        data = tuple(jnp.asarray(np.stack([pad(arrays[i]) for arrays in prepared])) for i in range(3))
        stacked = jax.tree_util.tree_map(lambda *leaves: jnp.stack(leaves), *models)
        checks = None
        if validate is not None:
            parts = [_padded_validation(h, max(len(v[0]) for v in held)) for h in held]
            checks = tuple(jnp.asarray(np.stack([part[i] for part in parts])) for i in range(4))
        result = fit(stacked, _step_loss, _index_rounds(counts, seeds, training), data, _config(training, True),
                     validate=validate, validation_data=checks, members=True)
        return [jax.tree_util.tree_map(lambda a: a[m], result.model) for m in range(len(sets))]
    out = []
    for model, arrays, count, seed, h in zip(models, prepared, counts, seeds, held):
        rounds = _index_rounds([count], [seed], training)
        checks = None if validate is None else tuple(jnp.asarray(a) for a in _padded_validation(h, len(h[0])))
        result = fit(model, _step_loss, lambda r: rounds(r)[0], tuple(jnp.asarray(a) for a in arrays),
                     _config(training, False), validate=validate, validation_data=checks)
        out.append(result.model)
    return out


@eqx.filter_jit
def _forward(model, packed):
    return jnp.clip(model(packed), 0.0, 1.0)


def predict(model: IspUNet, packed: np.ndarray, chunk: int = 64) -> np.ndarray:
    """The UNet's sRGB images of packed planes (N, h, w, 4), clipped to [0, 1].

    **Arguments:** `model` a trained `IspUNet`; `packed` (N, h, w, 4). **Returns:** (N, 2h, 2w, 3)
    float32."""
    x = np.asarray(packed, np.float32).transpose(0, 3, 1, 2)
    parts = [np.asarray(_forward(model, jnp.asarray(x[i:i + chunk]))) for i in range(0, len(x), chunk)]
    return np.concatenate(parts).transpose(0, 2, 3, 1) if parts else np.zeros((0, 2 * x.shape[2], 2 * x.shape[3], 3))


# ---------------------------------------------------------------- measures

def _pixel_weights(mask, shape) -> np.ndarray:
    """(N, H, W) float64 weights of the measured pixels: the mask, or 1 everywhere."""
    return np.ones(shape[:3]) if mask is None else np.asarray(mask, np.float64).reshape(shape[:3])


def _masked_mean(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Per-image mean of (N, ...) values over positions of weight 1; NaN for an image with none."""
    weights = weights.reshape(len(weights), -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sum(values.reshape(len(values), -1) * weights, axis=1) / np.sum(weights, axis=1)


def psnr(predicted: np.ndarray, target: np.ndarray, mask=None) -> np.ndarray:
    """Per-image PSNR (dB) of images in [0, 1]: 10 log10(1 / MSE), MSE over pixels and channels
    (the pixels where `mask` (N, H, W) is True, when given).

    **Arguments:** `predicted`, `target` (N, H, W, C); `mask`. **Returns:** (N,) float64 (inf where
    equal, NaN where the mask holds no pixel)."""
    diff = np.asarray(predicted, np.float64) - np.asarray(target, np.float64)
    mse = _masked_mean(np.mean(diff ** 2, axis=-1), _pixel_weights(mask, diff.shape))
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(1.0 / mse)


@functools.lru_cache(maxsize=4)
def _gaussian(size: int = 11, sigma: float = 1.5) -> np.ndarray:
    x = np.arange(size, dtype=np.float64) - (size - 1) / 2
    g = np.exp(-x ** 2 / (2 * sigma ** 2))
    return g / g.sum()


def _filter(x: np.ndarray, window: np.ndarray) -> np.ndarray:
    """'Valid' separable filtering of (N, H, W, C) over H and W."""
    n = len(window)
    rows = sum(window[i] * x[:, i:x.shape[1] - n + 1 + i] for i in range(n))
    return sum(window[i] * rows[:, :, i:rows.shape[2] - n + 1 + i] for i in range(n))


def ssim(predicted: np.ndarray, target: np.ndarray, mask=None, *, data_range: float = 1.0) -> np.ndarray:
    """Per-image SSIM (Wang, Bovik, Sheikh, Simoncelli, "Image Quality Assessment: From Error
    Visibility to Structural Similarity", IEEE TIP 13(4), 2004, Eq. 13): local means, variances
    and covariance under an 11 x 11 Gaussian window of sigma 1.5 (the paper's), 'valid' positions
    only, C1 = (0.01 L)^2, C2 = (0.03 L)^2 with L the data range; the mean over positions and
    channels (each channel on its own). With a `mask` (N, H, W), the mean over the positions whose
    whole window is True (NaN for an image with none).

    **Arguments:** `predicted`, `target` (N, H, W, C), H and W at least 11; `mask`; `data_range` L.
    **Returns:** (N,) float64 (NaN where no position is measured).
    """
    x, y = np.asarray(predicted, np.float64), np.asarray(target, np.float64)
    if x.shape != y.shape or x.ndim != 4 or min(x.shape[1:3]) < 11:
        raise ValueError(f"SSIM needs two (N, H, W, C) arrays of one shape, H, W >= 11; got {x.shape}, {y.shape}")
    window = _gaussian()
    mu_x, mu_y = _filter(x, window), _filter(y, window)
    var_x = _filter(x * x, window) - mu_x ** 2
    var_y = _filter(y * y, window) - mu_y ** 2
    cov = _filter(x * y, window) - mu_x * mu_y
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    index = ((2 * mu_x * mu_y + c1) * (2 * cov + c2)) / ((mu_x ** 2 + mu_y ** 2 + c1) * (var_x + var_y + c2))
    if mask is None:
        return index.reshape(len(index), -1).mean(axis=1)
    side = len(window)
    inside = _filter(_pixel_weights(mask, x.shape)[..., None], np.ones(side))[..., 0] >= side * side - 1e-9
    return _masked_mean(index.mean(axis=-1), inside.astype(np.float64))


def srgb_decoded(srgb) -> np.ndarray:
    """IEC 61966-2-1 decoding of sRGB values, clipped to [0, 1] first, in float64 (numpy)."""
    x = np.clip(np.asarray(srgb, np.float64), 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def delta_e_2000(predicted: np.ndarray, target: np.ndarray, mask=None) -> np.ndarray:
    """Per-image mean CIEDE2000 (Sharma, Wu, Dalal, Color Res. Appl. 30(1), 2005; colour-science's
    `delta_E(..., method='CIE 2000')`) between sRGB-coded images: IEC 61966-2-1 decoding, sRGB ->
    XYZ (D65), CIE Lab with the D65 white.

    **Arguments:** `predicted`, `target` (N, H, W, 3) in [0, 1]; `mask` (N, H, W): the pixels
    averaged (default all). **Returns:** (N,) float64 (NaN where the mask holds no pixel).
    """
    from g2r_jax.colour.conversions import MATRIX_SRGB_TO_XYZ, import_colour_science

    colour = import_colour_science()
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]

    def lab(image):
        return colour.XYZ_to_Lab(srgb_decoded(image) @ np.asarray(MATRIX_SRGB_TO_XYZ).T, white)

    difference = np.asarray(colour.delta_E(lab(predicted), lab(target), method="CIE 2000"), np.float64)
    return _masked_mean(difference, _pixel_weights(mask, difference.shape + (1,)))


def measure(predicted: np.ndarray, target: np.ndarray, mask=None) -> dict:
    """{'psnr', 'ssim', 'delta_e'}: each (N,) per image (see `psnr`, `ssim`, `delta_e_2000`), over
    the pixels of `mask` (N, H, W) when given.

    **Arguments:** `predicted`, `target` (N, H, W, 3) in [0, 1]; `mask`. **Returns:** the dict."""
    return {"psnr": psnr(predicted, target, mask), "ssim": ssim(predicted, target, mask),
            "delta_e": delta_e_2000(predicted, target, mask)}
