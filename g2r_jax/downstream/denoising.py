"""The denoising downstream test: a denoiser trained on synthetic noisy/clean RAW, tested on the
real noisy frames of a burst (Graphics2RAW, Seo et al. ICCV 2023, Table 1 protocol).

Test data: a `Burst` of one static scene (`g2r_jax.downstream.bursts`). Frame i's clean
reference is the mean of the other n - 1 frames. That mean keeps 1/(n-1) of the noise variance,
independent of frame i and of the denoiser, so it adds its own variance to every measured MSE:
E[(d - ref)^2] = E[(d - clean)^2] + var_ref. We correct for it: var_ref is measured per pixel
from the other frames themselves (their sample variance, ddof 1, divided by n - 1; no noise
model involved) and subtracted from the MSE before PSNR = 10 log10(1 / MSE), the range 1
being WhiteLevel - BlackLevel. `psnr_uncorrected` keeps the raw figure.

Training rows (all with one denoiser, `train_denoiser`: same network, steps, crops and seeds;
only the noisy inputs differ), each noise model at the burst's ISO:
- `upi`: the noise prior of Brooks et al. CVPR 2019, Sec. 3.2 (log-uniform shot, read from a
  log-log line with Gaussian scatter; `g2r_jax.downstream.upi.random_noise_levels`), per patch.
- `shipped`: the profile's NoiseModel (its level function and correlation where it has them)
  through `g2r_jax.sensor.add_noise`, the function `unprocess` uses, then the profile's banding.
- `fitted`: the noise `g2r-fit-profile` would fit from the burst's files
  (`g2r_jax.sensor.noise.fallback.noise_and_source`: NoiseProfile tags, else measured from the
  pixels), rounding kept in `read` as that fit keeps it.
- `truth`: the burst's photon transfer (`bursts.photon_transfer_noise`), or a known truth.
- `real`: real pairs, cross-validated: a training frame against the mean of the other
  training frames (a noisy target, unbiased for the clean one).

Contents: `cg` (CG images, e.g. CARLA frames, made clean RAW by `g2r_jax.unprocess_batch` with
the profile at the burst's ISO, then each row's noise) and `scene` (the burst's own clean
reference, the mean of the training frames: content-equal, the discriminating test of the
noise model). The scene mean of m frames still holds 1/m of the true noise variance, so the
rows add (1 - 1/m) of their model's variance on it: a true model then gives the true total.
Synthetic inputs are rounded to the burst's DN and clipped to [0, WhiteLevel] like real frames.
The noise parameters of `fitted` and `truth` come from all frames (8 numbers; the test frames'
share in them is negligible); everything else of the `scene` and `real` rows from the training
folds only.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.downstream.bursts import Burst, photon_transfer_noise, read_burst

ROWS = ("upi", "shipped", "fitted", "truth", "real")
CONTENTS = ("cg", "scene")
ROW_NAMES = {"upi": "UPI noise (Brooks 2019)", "shipped": "g2r_jax shipped profile", "fitted":
             "g2r_jax fitted from the burst", "truth": "photon-transfer truth", "real": "real pairs (cross-validated)"}
CONTENT_NAMES = {"cg": "CG content", "scene": "real scene (content-equal)"}

# The denoiser and its training (`train_denoiser`): a DnCNN-like residual CNN (Zhang et al.,
# "Beyond a Gaussian Denoiser", IEEE TIP 2017) on the 4 packed CFA planes, L2 loss, Adam.
WIDTH = 16
DEPTH = 4                 # 3x3 convolutions: receptive field 9x9 planes (18x18 mosaic pixels)
PATCH = 32                # training crops, in planes (64x64 mosaic pixels)
BATCH = 8
LEARNING_RATE = 1e-3
STEPS = 300
TILE = 256                # test frames are denoised in strips of this many plane rows


# ----------------------------------------------------------------------------- noise models

@dataclasses.dataclass(frozen=True)
class NoiseSpec:
    """One row's noise model in normalised units at the burst's ISO: variance = shot * x + read
    per tile position (or `level_variance` (4, K) at `level_knots`), optional `correlation_kernel`
    (4, 3, 3) with its share by level (`correlation_knots`, `correlation_weight`), banding stds;
    `upi`: draw (shot, read) per patch from UPI's prior instead."""

    upi: bool = False
    shot: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(4, np.float32))
    read: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(4, np.float32))
    level_knots: np.ndarray | None = None
    level_variance: np.ndarray | None = None
    correlation_kernel: np.ndarray | None = None
    correlation_knots: np.ndarray | None = None
    correlation_weight: np.ndarray | None = None
    row_noise_std: float = 0.0
    column_noise_std: float = 0.0
    description: str = ""


def _at_iso(noise, iso: float):
    from g2r_jax import sensor

    shot, read = (np.asarray(v, np.float32) for v in sensor.noise_parameters(jnp.float32(iso), noise))
    level = sensor.noise_level_at(jnp.float32(iso), noise)
    return shot, read, None if level is None else np.asarray(level, np.float32)


def _optional(value):
    return None if value is None else np.asarray(value, np.float32)


def _describe(shot, read) -> str:
    return f"shot {np.mean(shot):.3g}, read {np.mean(read):.3g} (mean of 4 positions)"


def noise_spec(row: str, burst: Burst, profile, truth_noise=None) -> NoiseSpec:
    """The `NoiseSpec` of a synthetic row ('upi', 'shipped', 'fitted', 'truth') for `burst`."""
    if row == "upi":
        return NoiseSpec(upi=True, description="drawn per patch: shot log-uniform in [1e-4, 1.2e-2], "
                                               "log read = 2.18 log shot + 1.20 + N(0, 0.26)")
    if row == "shipped":
        noise = profile.noise
        shot, read, level = _at_iso(noise, burst.iso)
        low, high = float(np.min(noise.iso)), float(np.max(noise.iso))
        outside = "" if low * 0.98 <= burst.iso <= high * 1.02 else \
            f"; ISO {burst.iso:g} outside the profile's calibrated {low:g}-{high:g}: held at the nearest row"
        return NoiseSpec(shot=shot, read=read, level_knots=None if level is None else np.asarray(noise.level_knots),
                         level_variance=level, correlation_kernel=_optional(noise.correlation_kernel),
                         correlation_knots=_optional(noise.correlation_knots),
                         correlation_weight=_optional(noise.correlation_weight),
                         row_noise_std=float(profile.effects.row_noise_std),
                         column_noise_std=float(profile.effects.column_noise_std),
                         description=_describe(shot, read) + (", with level function" if level is not None else "")
                         + outside)
    if row == "fitted":
        from g2r_jax.sensor.noise.fallback import noise_and_source

        with warnings.catch_warnings(record=True):
            warnings.simplefilter("always")
            model, source = noise_and_source(list(burst.infos), burst.cfa_pattern)
        shot, read, _ = _at_iso(model, burst.iso)
        return NoiseSpec(shot=shot, read=read, description=f"{_describe(shot, read)}; {source}")
    if row == "truth":
        if truth_noise is None:
            shot, read = photon_transfer_noise(burst)
            where = f"photon transfer over the {burst.n} frames"
        else:
            shot, read = (np.resize(np.asarray(v, np.float64), 4) for v in truth_noise)
            where = "known truth"
        if not (np.all(np.isfinite(shot)) and np.all(np.isfinite(read))):
            raise ValueError(f"photon transfer gave no noise line for this burst (shot {shot}, read {read}): "
                             f"its pixels do not span a range of signals")
        return NoiseSpec(shot=np.asarray(shot, np.float32), read=np.asarray(read, np.float32),
                         description=f"{_describe(shot, read)}; {where}")
    raise ValueError(f"unknown synthetic row {row!r}; expected one of upi, shipped, fitted, truth")


def _noise_arrays(spec: NoiseSpec) -> dict:
    """The arrays of a non-UPI `spec` as a pytree (a jit argument; absent parts None)."""
    as_array = lambda a: None if a is None else jnp.asarray(a, jnp.float32)
    return {"shot": as_array(spec.shot), "read": as_array(spec.read), "level_knots": as_array(spec.level_knots),
            "level_variance": as_array(spec.level_variance), "kernel": as_array(spec.correlation_kernel),
            "correlation_knots": as_array(spec.correlation_knots),
            "correlation_weight": as_array(spec.correlation_weight),
            "banding": jnp.asarray([spec.row_noise_std, spec.column_noise_std], jnp.float32)}


def synthetic_noisy(key, clean, noise: dict, upi: bool, factor, black, span, white):
    """Noisy planes (B, 4, h, w) for clean planes `clean` (normalised): the noise of
    `_noise_arrays` (or UPI's prior per patch when `upi`) with `factor` times its variance,
    rounded to the burst's DN (`black`, `span` (4,), `white`) and clipped to [0, WhiteLevel]
    as a sensor's output is."""
    from g2r_jax import sensor

    batch = clean.shape[0]
    k_levels, k_noise, k_readout = jax.random.split(key, 3)
    if upi:
        from g2r_jax.downstream.upi import random_noise_levels

        shot, read = jax.vmap(random_noise_levels)(jax.random.split(k_levels, batch))
        shot, read = jnp.repeat(shot[:, None], 4, 1), jnp.repeat(read[:, None], 4, 1)
        noise = {"level_knots": None, "level_variance": None, "kernel": None, "correlation_knots": None,
                 "correlation_weight": None, "banding": jnp.zeros(2)}
    else:
        shot, read = jnp.broadcast_to(noise["shot"], (batch, 4)), jnp.broadcast_to(noise["read"], (batch, 4))
    level = None if noise["level_variance"] is None else noise["level_variance"] * factor

    def one(k, planes, s, r):
        mosaic = sensor.add_noise(k, sensor.from_planes(planes), s * factor, r * factor,
                                  level_knots=noise["level_knots"], level_variance=level,
                                  correlation_kernel=noise["kernel"],
                                  correlation_levels=(noise["correlation_knots"], noise["correlation_weight"]))
        return sensor.to_planes(mosaic)

    noisy = jax.vmap(one)(jax.random.split(k_noise, batch), clean, shot, read)
    k_rows, k_cols = jax.random.split(k_readout)
    h, w = noisy.shape[-2:]
    banding = noise["banding"] * jnp.sqrt(factor)
    noisy = noisy + (banding[0] * jax.random.normal(k_rows, (batch, 1, h, 1))
                     + banding[1] * jax.random.normal(k_cols, (batch, 1, 1, w)))
    black, span = black[:, None, None], span[:, None, None]
    digital = jnp.clip(jnp.round(noisy * span + black), 0.0, white)
    return (digital - black) / span


# ----------------------------------------------------------------------------- the denoiser

def init_denoiser(key, width: int = WIDTH, depth: int = DEPTH):
    """Parameters [(kernel (out, in, 3, 3), bias (out,)), ...] of `depth` 3x3 convolutions,
    4 -> width -> ... -> 4 channels, He-initialised (the last layer at 1/10 so that training
    starts near the identity)."""
    sizes = [4] + [width] * (depth - 1) + [4]
    params = []
    for k, (n_in, n_out) in zip(jax.random.split(key, depth), zip(sizes[:-1], sizes[1:])):
        scale = np.sqrt(2.0 / (9 * n_in)) * (0.1 if n_out == 4 else 1.0)
        params.append((scale * jax.random.normal(k, (n_out, n_in, 3, 3), jnp.float32), jnp.zeros(n_out, jnp.float32)))
    return params


def apply_denoiser(params, noisy, gain):
    """Denoised planes (B, 4, h, w): noisy - CNN(gain * noisy) / gain (residual learning; `gain`
    brings the scene's signal near 1 so that a dim scene trains like a bright one)."""
    x = noisy * gain
    for k, (kernel, bias) in enumerate(params):
        x = jax.lax.conv_general_dilated(x, kernel, (1, 1), "SAME", dimension_numbers=("NCHW", "OIHW", "NCHW"))
        x = x + bias[None, :, None, None]
        if k < len(params) - 1:
            x = jax.nn.relu(x)
    return noisy - x / gain


def _crops(rng, images: np.ndarray, batch: int, patch: int):
    """(indices, rows, cols) of `batch` random (4, patch, patch) crops of images (N, 4, h, w)."""
    n, _, h, w = images.shape
    return rng.integers(0, n, batch), rng.integers(0, h - patch + 1, batch), rng.integers(0, w - patch + 1, batch)


def _cut(images: np.ndarray, index, rows, cols, patch: int) -> np.ndarray:
    return np.stack([images[i, :, r:r + patch, c:c + patch] for i, r, c in zip(index, rows, cols)])


def _learning_rate(step: int, steps: int) -> float:
    """Cosine decay from LEARNING_RATE to a tenth of it (Loshchilov & Hutter, SGDR, ICLR 2017)."""
    return LEARNING_RATE * (0.1 + 0.9 * 0.5 * (1.0 + np.cos(np.pi * step / max(steps - 1, 1))))


@partial(jax.jit, static_argnames=("upi",))
def _train_step(params, state, key, noisy_or_clean, clean, learning_rate, gain, factor, black, span, white, noise, *,
                upi):
    """One Adam step (Kingma & Ba, ICLR 2015) on a batch of crops: `clean` with synthetic noise
    when `noise` is given or `upi`, else the real pair (`noisy_or_clean`, `clean`). One jitted
    step called from Python: inside a `lax.scan` XLA's CPU convolutions ran about 7 times slower
    per step (measured, 2 cores)."""
    import optax

    synthetic = upi or noise is not None
    noisy = synthetic_noisy(key, clean, noise, upi, factor, black, span, white) if synthetic else noisy_or_clean
    loss = lambda p: jnp.mean(((apply_denoiser(p, noisy, gain) - clean) * gain) ** 2)
    value, grads = jax.value_and_grad(loss)(params)
    updates, state = optax.scale_by_adam().update(grads, state, params)
    updates = jax.tree_util.tree_map(lambda u: -learning_rate * u, updates)
    return optax.apply_updates(params, updates), state, value


def train_denoiser(key, burst: Burst, targets, *, inputs=None, spec: NoiseSpec | None = None, factor: float = 1.0,
                   gain: float = 1.0, steps: int = STEPS):
    """Parameters of a denoiser trained for `steps` Adam steps on random crops of `targets`
    (N, 4, h, w) normalised planes: with `spec`, the inputs are `targets` with that noise
    (`synthetic_noisy`, `factor` times its variance, in the burst's DN); without, the crops of
    `inputs` at the same places (real pairs). Returns (params, losses)."""
    import optax

    targets = np.asarray(targets, np.float32)
    inputs = targets if inputs is None else np.asarray(inputs, np.float32)
    levels = (jnp.asarray(burst.black, jnp.float32), jnp.asarray(burst.span, jnp.float32), jnp.float32(burst.white))
    patch = min(PATCH, targets.shape[-2], targets.shape[-1])
    upi = spec is not None and spec.upi
    noise = _noise_arrays(spec) if spec is not None and not upi else None
    k_init, k_crops, k_steps = jax.random.split(key, 3)
    rng = np.random.default_rng(np.asarray(jax.random.key_data(k_crops)).tolist())
    params = init_denoiser(k_init)
    state = optax.scale_by_adam().init(params)
    losses = []
    for step, k in enumerate(jax.random.split(k_steps, steps)):
        where = _crops(rng, targets, BATCH, patch)
        params, state, value = _train_step(params, state, k, _cut(inputs, *where, patch), _cut(targets, *where, patch),
                                           jnp.float32(_learning_rate(step, steps)), jnp.float32(gain),
                                           jnp.float32(factor), *levels, noise, upi=upi)
        losses.append(value)
    return params, np.asarray(jnp.stack(losses))


@jax.jit
def _denoise(params, planes, gain):
    return apply_denoiser(params, planes[None], gain)[0]


def denoise(params, planes, gain) -> np.ndarray:
    """Denoised (4, H, W) planes, in strips of TILE rows with a halo of DEPTH rows (the network's
    reach), so that a 12-MP frame needs no more memory than a strip."""
    planes = np.asarray(planes, np.float32)
    height = planes.shape[1]
    if height <= TILE:
        return np.asarray(_denoise(params, planes, gain))
    halo = len(params)
    out = np.empty_like(planes)
    for top in range(0, height, TILE):
        lo, hi = max(top - halo, 0), min(top + TILE + halo, height)
        strip = np.asarray(_denoise(params, planes[:, lo:hi], gain))
        out[:, top:min(top + TILE, height)] = strip[:, top - lo: top - lo + min(TILE, height - top)]
    return out


# ----------------------------------------------------------------------------- PSNR

def psnr(denoised, reference, reference_variance=0.0) -> float:
    """PSNR (dB) on the range 1 (WhiteLevel - BlackLevel) of normalised planes against a noisy
    `reference` whose own noise variance (mean over pixels) is `reference_variance`: that
    variance is taken out of the mean squared error (see the module docstring). NaN when the
    corrected error is not positive."""
    mse = float(np.mean((np.asarray(denoised, np.float64) - np.asarray(reference, np.float64)) ** 2))
    corrected = mse - float(reference_variance)
    return 10.0 * np.log10(1.0 / corrected) if corrected > 0 else float("nan")


def reference_and_variance(burst: Burst, index: int, sums=None):
    """(reference (4, H, W), its mean noise variance): the mean of the other frames and the mean
    over pixels of their sample variance (ddof 1) / (n - 1). `sums`: `frame_sums(burst)`, so
    that many frames cost one pass over the burst."""
    n = burst.n
    total, squares = frame_sums(burst) if sums is None else sums
    frame = burst.planes[index].astype(np.float64)
    reference = (total - frame) / (n - 1)
    variance = (squares - frame * frame - (n - 1) * reference * reference) / (n - 2)
    return reference, float(np.mean(variance) / (n - 1))


def frame_sums(burst: Burst):
    """(sum, sum of squares) of the burst's frames, float64 (4, H, W)."""
    total, squares = np.zeros(burst.planes.shape[1:]), np.zeros(burst.planes.shape[1:])
    for frame in burst.planes:
        frame = frame.astype(np.float64)
        total += frame
        squares += frame * frame
    return total, squares


# ----------------------------------------------------------------------------- the benchmark

@dataclasses.dataclass
class DenoisingResult:
    """`psnr[(row, content)]`: mean PSNR (dB, corrected) over the test frames, one value per
    seed; `psnr_uncorrected` the same against the noisy reference as is; `noisy_psnr` the test
    frames themselves (no denoiser); `noise` {row: description}; `frames`, `skipped`, `iso`,
    `folds`, `seeds`, `steps`, `seconds` {row: training seconds per seed}."""

    psnr: dict
    psnr_uncorrected: dict
    noisy_psnr: float
    noise: dict
    frames: tuple
    skipped: tuple
    iso: float
    folds: int
    seeds: tuple
    steps: int
    cg_images: int
    seconds: dict

    def table(self) -> str:
        """A markdown table: rows x contents, mean +- sd over seeds (and the seeds' range)."""
        contents = [c for c in CONTENTS if any(k[1] == c for k in self.psnr)]
        head = "| noise model | " + " | ".join(CONTENT_NAMES[c] + " (dB)" for c in contents) + " |"
        lines = [head, "|---|" + "---|" * len(contents)]
        rows = [r for r in ROWS if any(k[0] == r for k in self.psnr)]
        for row in rows:
            cells = []
            for content in contents:
                values = np.asarray(self.psnr.get((row, content), []), np.float64)
                if values.size == 0:
                    cells.append("-")
                elif values.size == 1:
                    cells.append(f"{values[0]:.2f}")
                else:
                    cells.append(f"{values.mean():.2f} ± {values.std(ddof=1):.2f} "
                                 f"({values.min():.2f}-{values.max():.2f})")
            lines.append(f"| {ROW_NAMES[row]} | " + " | ".join(cells) + " |")
        lines.append("| noisy input (no denoiser) | " + " | ".join(f"{self.noisy_psnr:.2f}" for _ in contents) + " |")
        return "\n".join(lines)

    def summary(self) -> str:
        """The table, the noise models and the protocol in a few lines."""
        noise = "\n".join(f"- {ROW_NAMES[r]}: {d}" for r, d in self.noise.items())
        skipped = "; ".join(f"{n}: {w}" for n, w in self.skipped) or "none"
        return (f"{len(self.frames)} frames at ISO {self.iso:g}, {self.folds} folds, seeds {list(self.seeds)}, "
                f"{self.steps} steps, {self.cg_images} CG images; PSNR on WhiteLevel - BlackLevel, the reference's "
                f"own noise taken out\n\n{self.table()}\n\nnoise at ISO {self.iso:g}:\n{noise}\n"
                f"skipped files: {skipped}")


def _folds(n: int, folds: int) -> list[list[int]]:
    """Interleaved test folds of n frames, as many as asked but with at least 2 training frames
    each (the real pairs need a frame and a mean of others): n = 3 gives leave-one-out."""
    folds = max(2, min(int(folds), n))
    while n - int(np.ceil(n / folds)) < 2 and folds < n:
        folds += 1
    return [list(range(k, n, folds)) for k in range(folds)]


def _load_cg(images, count: int) -> np.ndarray:
    """(N, H, W, 3) uint8 of the first `count` CG images (paths or arrays), centre-cropped to
    their common even size."""
    from g2r_jax.io import images as image_io

    items = list(images)[:count]
    paths = [item for item in items if isinstance(item, (str, Path))]
    arrays = [np.asarray(item) for item in items if not isinstance(item, (str, Path))]
    arrays += [np.round(np.clip(values, 0, 1) * 255).astype(np.uint8) for _, values, _ in image_io.read_images(paths)]
    if not arrays:
        raise ValueError("the 'cg' content needs CG images (cg_images)")
    h = min(a.shape[0] for a in arrays) // 2 * 2
    w = min(a.shape[1] for a in arrays) // 2 * 2
    crop = lambda a: a[(a.shape[0] - h) // 2:(a.shape[0] - h) // 2 + h, (a.shape[1] - w) // 2:(a.shape[1] - w) // 2 + w]
    return np.stack([crop(a)[..., :3] for a in arrays])


def clean_cg_planes(images, profile, iso: float, seed: int) -> np.ndarray:
    """(N, 4, H/2, W/2) normalised clean RAW of CG images (N, H, W, 3) uint8: `unprocess_batch`
    with the profile (its illuminants, exposure and sensor effects; ISO fixed), no noise."""
    import g2r_jax
    from g2r_jax.pipeline import image_key
    from g2r_jax import sensor

    keys = jnp.stack([image_key(seed, k) for k in range(len(images))])
    _, clean, _ = g2r_jax.unprocess_batch(keys, jnp.asarray(images), profile, iso=float(iso), noise=False,
                                          quantize=False, return_clean=True)
    black = np.resize(np.asarray(profile.black_level, np.float64), 4)
    span = float(profile.white_level) - black
    planes = jax.vmap(sensor.to_planes)(clean)
    planes = (np.asarray(planes, np.float64) - black[None, :, None, None]) / span[None, :, None, None]
    return planes.astype(np.float32)


def denoising_benchmark(burst, profile, cg_images=(), *, rows=ROWS, contents=CONTENTS, seeds=(0, 1, 2),
                        steps: int = STEPS, folds: int = 2, truth_noise=None, cg_count: int = 32,
                        progress=None) -> DenoisingResult:
    """The denoising test on a burst (a `Burst`, or a folder / list of DNGs for `read_burst`).

    **Arguments:** `profile` the camera's SensorProfile (its CFA pattern must be the burst's);
    `cg_images` paths or (H, W, 3) uint8 arrays (the first `cg_count` are used) for the `cg`
    content; `rows` a subset of ROWS, `contents` of CONTENTS; `seeds`: each seed draws the
    network's initialisation, crops, noise and the CG images' illuminants; one seed gives every
    row the same draws (a paired comparison); `steps` Adam steps per training; `folds` test
    folds of the frames (interleaved; at least 2 training frames each); `truth_noise` optional
    (shot (4,), read (4,)) for the `truth` row instead of photon transfer; `progress` a
    callable taking one line of text.
    """
    say = progress or (lambda line: None)
    if not isinstance(burst, Burst):
        burst = read_burst(burst)
    unknown = [r for r in rows if r not in ROWS] + [c for c in contents if c not in CONTENTS]
    if unknown:
        raise ValueError(f"unknown rows/contents {unknown}; rows are {ROWS}, contents {CONTENTS}")
    profile_cfa = tuple(int(c) for c in np.asarray(profile.cfa_pattern))
    if profile_cfa != burst.cfa_pattern:
        raise ValueError(f"the profile's CFA pattern {profile_cfa} is not the burst's {burst.cfa_pattern} "
                         f"({burst.names[0]}): a profile of another camera?")
    synthetic = [r for r in rows if r != "real"]
    specs = {r: noise_spec(r, burst, profile, truth_noise) for r in synthetic}
    noise = {r: specs[r].description for r in synthetic}
    if "real" in rows:
        noise["real"] = "the burst's own frames (training folds)"
    test_folds = _folds(burst.n, folds)
    sums = frame_sums(burst)
    reference_variance = [reference_and_variance(burst, i, sums)[1] for i in range(burst.n)]
    reference = lambda i: (sums[0] - burst.planes[i]) / (burst.n - 1)
    noisy_psnr = float(np.mean([psnr(burst.planes[i], reference(i), reference_variance[i]) for i in range(burst.n)]))
    gain = 0.5 / max(float(np.quantile(burst.planes.mean(0), 0.99)), 1e-4)
    cg = _load_cg(cg_images, cg_count) if "cg" in contents and synthetic else None

    def score(params, frames):
        corrected, raw = {}, {}
        for i in frames:
            denoised = denoise(params, burst.planes[i], gain)
            corrected[i] = psnr(denoised, reference(i), reference_variance[i])
            raw[i] = psnr(denoised, reference(i))
        return corrected, raw

    results = {(r, c): [] for r in rows for c in contents if not (r == "real" and c == "cg")}
    uncorrected = {k: [] for k in results}
    seconds = {r: [] for r in rows}
    for seed in seeds:
        base = jax.random.PRNGKey(int(seed))
        cg_planes = None if cg is None else clean_cg_planes(cg, profile, burst.iso, int(seed))
        for row in rows:
            started = time.perf_counter()
            for content in contents:
                if (row, content) not in results:
                    continue
                per_frame, per_frame_raw = {}, {}
                if content == "cg":
                    params, _ = train_denoiser(jax.random.fold_in(base, 0), burst, cg_planes, spec=specs[row],
                                               gain=gain, steps=steps)
                    got = score(params, range(burst.n))
                    per_frame.update(got[0]), per_frame_raw.update(got[1])
                else:
                    for k, test in enumerate(test_folds):
                        train = [i for i in range(burst.n) if i not in test]
                        key = jax.random.fold_in(base, 1 + k)
                        if row == "real":
                            targets = np.stack([burst.mean_of_others(i, train) for i in train])
                            params, _ = train_denoiser(key, burst, targets, inputs=burst.planes[train], gain=gain,
                                                       steps=steps)
                        else:
                            params, _ = train_denoiser(key, burst, burst.planes[train].mean(0)[None],
                                                       spec=specs[row], factor=1.0 - 1.0 / len(train), gain=gain,
                                                       steps=steps)
                        got = score(params, test)
                        per_frame.update(got[0]), per_frame_raw.update(got[1])
                results[(row, content)].append(float(np.mean(list(per_frame.values()))))
                uncorrected[(row, content)].append(float(np.mean(list(per_frame_raw.values()))))
                say(f"seed {seed} {row:8s} {content:6s} {results[(row, content)][-1]:.2f} dB")
            seconds[row].append(time.perf_counter() - started)
    return DenoisingResult(psnr=results, psnr_uncorrected=uncorrected, noisy_psnr=noisy_psnr, noise=noise,
                           frames=burst.names, skipped=burst.skipped, iso=burst.iso, folds=len(test_folds),
                           seeds=tuple(seeds), steps=steps, cg_images=0 if cg is None else len(cg), seconds=seconds)
