"""The burst check's denoiser: a DnCNN-like residual CNN (Zhang et al., "Beyond a Gaussian
Denoiser", IEEE TIP 2017) on the 4 packed CFA planes, an equinox module trained with L2 loss by
the one training base (`g2r_jax.downstream.base.training.fit`: Adam, cosine decay to a tenth).

Inputs and targets are normalised planes (N, 4, h, w), x = (DN - BlackLevel) / (WhiteLevel -
BlackLevel). A training's inputs are either real noisy crops (real pairs) or the targets with
synthetic noise drawn inside the step (`synthetic_noisy`, a function of the key, so that every
row of one seed sees the same crops and draws).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.downstream.base.training import LoopConfig, fit

WIDTH = 16
DEPTH = 4                 # 3x3 convolutions: receptive field 9x9 planes (18x18 mosaic pixels)
TILE = 256                # test frames are denoised in strips of this many plane rows


@dataclasses.dataclass(frozen=True)
class DenoiserTraining:
    """Crops and optimiser of one denoiser training: `batch` crops of `patch` x `patch` planes per
    Adam step, peak learning rate `learning_rate` decayed (cosine) to a tenth over the run, rounds
    of `steps_per_round` steps."""

    patch: int = 32
    batch: int = 8
    learning_rate: float = 1e-3
    steps_per_round: int = 100


class ResidualDenoiser(eqx.Module):
    """`depth` 3x3 convolutions 4 -> width -> ... -> 4 (OIHW kernels), ReLU between; denoised =
    noisy - CNN(gain * noisy) / gain (residual learning; `gain` brings the scene's signal near 1
    so that a dim scene trains like a bright one)."""

    kernels: tuple
    biases: tuple

    def __call__(self, noisy, gain):
        x = noisy * gain
        for k, (kernel, bias) in enumerate(zip(self.kernels, self.biases)):
            x = jax.lax.conv_general_dilated(x, kernel, (1, 1), "SAME", dimension_numbers=("NCHW", "OIHW", "NCHW"))
            x = x + bias[None, :, None, None]
            if k < len(self.kernels) - 1:
                x = jax.nn.relu(x)
        return noisy - x / gain


def init_denoiser(key, width: int = WIDTH, depth: int = DEPTH) -> ResidualDenoiser:
    """He-initialised (He et al., ICCV 2015) kernels, zero biases; the last layer at 1/10 so that
    training starts near the identity."""
    sizes = [4] + [width] * (depth - 1) + [4]
    kernels, biases = [], []
    for k, (n_in, n_out) in zip(jax.random.split(key, depth), zip(sizes[:-1], sizes[1:])):
        scale = np.sqrt(2.0 / (9 * n_in)) * (0.1 if n_out == 4 else 1.0)
        kernels.append(scale * jax.random.normal(k, (n_out, n_in, 3, 3), jnp.float32))
        biases.append(jnp.zeros(n_out, jnp.float32))
    return ResidualDenoiser(tuple(kernels), tuple(biases))


@functools.lru_cache(maxsize=None)
def step_loss_for(noise_fn: Callable | None):
    """The loss of one step for `fit`: step_input (key, inputs, targets) crops, data (gain,
    noise_data); with `noise_fn(key, inputs, noise_data)` the noisy inputs are drawn on the given
    inputs (clean content, or a mean of frames whose own residual noise the draw completes),
    else the given inputs are used as they are (real pairs). L2 in the gained units."""

    def step_loss(model, step_input, data):
        key, inputs, targets = step_input
        gain, noise_data = data
        noisy = inputs if noise_fn is None else noise_fn(key, inputs, noise_data)
        return jnp.mean(((model(noisy, gain) - targets) * gain) ** 2)

    return step_loss


def _validation_error(model, validation):
    """10 log10 of the mean squared error of the denoised validation crops against their
    references (dB; the references' own noise is a constant offset and does not change which
    round is best)."""
    noisy, reference, gain = validation
    return 10.0 * jnp.log10(jnp.mean((model(noisy, gain) - reference) ** 2))


def crop_rounds(key, inputs: np.ndarray, targets: np.ndarray, training: DenoiserTraining):
    """round_inputs(r) for `fit`: (keys, input crops, target crops) of `steps_per_round` steps of
    `batch` random crops at the same places of `inputs` and `targets` (N, 4, h, w), drawn from
    `key` (round r from fold_in(key, r))."""
    patch = min(training.patch, targets.shape[-2], targets.shape[-1])
    n, _, h, w = targets.shape
    count = training.steps_per_round * training.batch

    def round_inputs(r):
        k_noise, k_crops = jax.random.split(jax.random.fold_in(key, r))
        rng = np.random.default_rng(np.asarray(jax.random.key_data(k_crops)).tolist())
        index, rows, cols = rng.integers(0, n, count), rng.integers(0, h - patch + 1, count), \
            rng.integers(0, w - patch + 1, count)
        cut = lambda images: np.stack([images[i, :, y:y + patch, x:x + patch] for i, y, x in zip(index, rows, cols)])
        shape = (training.steps_per_round, training.batch, 4, patch, patch)
        return (jax.random.split(k_noise, training.steps_per_round), cut(inputs).reshape(shape),
                cut(targets).reshape(shape))

    return round_inputs


def train_denoiser(key, targets, *, inputs=None, noise_fn=None, noise_data=None, gain: float = 1.0,
                   steps: int = 1000, training: DenoiserTraining = DenoiserTraining(), validation=None,
                   patience: int | None = None, min_improvement: float = 0.02):
    """Train a `ResidualDenoiser` for at most `steps` Adam steps (rounded up to whole rounds) on
    random crops of `targets` (N, 4, h, w) and of `inputs` (default: the targets) at the same
    places: the noisy inputs are `noise_fn`'s draws on the input crops (synthetic rows), or the
    input crops themselves (real pairs).

    With `validation` (noisy crops, reference crops, both (V, 4, p, p)), the model of the round
    with the lowest validation error is kept and training stops once `patience` rounds in a row
    improve on it by no more than `min_improvement` dB. **Returns:** `training.FitResult`.
    """
    targets = np.asarray(targets, np.float32)
    inputs = targets if inputs is None else np.asarray(inputs, np.float32)
    k_init, k_rounds = jax.random.split(key)
    rounds = max(1, -(-int(steps) // training.steps_per_round))
    config = LoopConfig(rounds=rounds, steps_per_round=training.steps_per_round,
                        learning_rate=training.learning_rate, final_fraction=0.1, patience=patience,
                        min_improvement=min_improvement, scan=False)
    data = (jnp.float32(gain), noise_data)
    check = None
    if validation is not None:
        check = (jnp.asarray(validation[0]), jnp.asarray(validation[1]), jnp.float32(gain))
    return fit(init_denoiser(k_init), step_loss_for(noise_fn), crop_rounds(k_rounds, inputs, targets, training),
               data, config, validate=None if validation is None else _validation_error, validation_data=check)


@eqx.filter_jit
def _denoise(model, planes, gain):
    return model(planes[None], gain)[0]


def denoise(model, planes, gain) -> np.ndarray:
    """Denoised (4, H, W) planes, in strips of TILE rows with a halo of the network's depth, so
    that a 12-MP frame needs no more memory than a strip."""
    planes = np.asarray(planes, np.float32)
    height = planes.shape[1]
    if height <= TILE:
        return np.asarray(_denoise(model, planes, gain))
    halo = len(model.kernels)
    out = np.empty_like(planes)
    for top in range(0, height, TILE):
        lo, hi = max(top - halo, 0), min(top + TILE + halo, height)
        strip = np.asarray(_denoise(model, planes[:, lo:hi], gain))
        out[:, top:min(top + TILE, height)] = strip[:, top - lo: top - lo + min(TILE, height - top)]
    return out
