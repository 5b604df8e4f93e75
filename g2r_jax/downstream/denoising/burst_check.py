"""The denoising check: a denoiser trained on synthetic noisy/clean RAW, tested on the real noisy
frames of a burst (Graphics2RAW, Seo et al. ICCV 2023, Table 1 protocol); `run_burst_check`.

Test data: a `Burst` of one static scene (`g2r_jax.downstream.denoising.bursts`). Frame i's clean
reference is the mean of the other n - 1 frames. That mean keeps 1/(n-1) of the noise variance,
independent of frame i and of the denoiser, so it adds its own variance to every measured MSE:
E[(d - ref)^2] = E[(d - clean)^2] + var_ref. We correct for it: var_ref is measured per pixel
from the other frames themselves (their sample variance, ddof 1, divided by n - 1; no noise
model involved) and subtracted from the MSE before PSNR = 10 log10(peak^2 / MSE). The peak is
the scene's PEAK_QUANTILE (99.9th percentile of the mean of all frames), not the white level: on
a dim burst the white level would inflate every PSNR by the same large constant.
`psnr_uncorrected` keeps the raw figure.

Training rows (all with one denoiser, `g2r_jax.downstream.denoising.denoiser`: same network, steps, crops
and seeds; only the noisy inputs differ), each noise model at the burst's ISO:
- `upi`: the noise prior of Brooks et al. CVPR 2019, Sec. 3.2 (log-uniform shot, read from a
  log-log line with Gaussian scatter; `g2r_jax.downstream.base.upi.random_noise_levels`), per patch.
- `shipped`: the profile's NoiseModel (its level function and correlation where it has them)
  through the simulation's readout stage (`g2r_jax.sensor.readout`), with the profile's banding.
- `fitted`: the noise `g2r-fit-profile` would fit from the burst's files
  (`g2r_jax.sensor.noise.fallback.noise_and_source`: NoiseProfile tags, else measured from the
  pixels), rounding kept in `read` as that fit keeps it.
- `truth`: the burst's photon transfer (`bursts.photon_transfer_noise`), or a known truth.
- `real`: real pairs, cross-validated: a training frame against the mean of the other
  training frames (a noisy target, unbiased for the clean one).

How long: every training runs the same number of Adam steps, chosen per burst by `choose_steps`
(a validation split of the burst: the real-pairs row trained until its validation error stops
improving, with a cap), so that the rows compare converged denoisers, not how much a short run
smooths. Seeds: the verdict (`verdict_sentence`, `compare_rows`) names a difference between two
rows only when their seeds' ranges do not overlap, "within training noise" otherwise.

Contents: `cg` (CG images, e.g. CARLA frames, made clean RAW by `g2r_jax.unprocess_batch` with
the profile at the burst's ISO, then brought to the burst's own signal levels by `match_levels`:
each frame's median and 99th percentile set to the scene's; then each row's noise) and `scene`
(the burst's own scene: content-equal, the discriminating test of the noise model). The
training frames are split in two interleaved halves; the input is the mean of one half (m
frames, holding 1/m of the true noise variance) plus (1 - 1/m) of the row's model variance, so
a true model gives the true total, and the target is the mean of the other half: a noisy target
independent of the input (Noise2Noise, Lehtinen et al., ICML 2018), so the denoiser learns to
remove the mean's residual noise too instead of keeping it as texture (with the half's own mean
as the target, a dim defocused scene, whose texture is all noise, cost the true models 1.8 dB
against real pairs). Both halves serve in turn as input and target. Synthetic inputs are rounded to the burst's DN and clipped to [0,
WhiteLevel] like real frames. The noise parameters of `fitted` and `truth`, the PSNR peak, the
denoiser's input gain and the CG levels come from all frames (a few numbers; the test frames'
share in them is negligible); everything else of the `scene` and `real` rows from the training
folds only.
"""

from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.downstream.base.progress import advance
from g2r_jax.downstream.denoising.bursts import Burst, read_burst
from g2r_jax.downstream.denoising.denoiser import DenoiserTraining, denoise, train_denoiser
from g2r_jax.downstream.denoising.noise import noise_spec, training_noise

ROWS = ("upi", "shipped", "fitted", "truth", "real")
CONTENTS = ("cg", "scene")
ROW_NAMES = {"upi": "UPI noise (Brooks 2019)", "shipped": "g2r_jax shipped profile", "fitted":
             "g2r_jax fitted from the burst", "truth": "photon-transfer truth", "real": "real pairs (cross-validated)"}
CONTENT_NAMES = {"cg": "CG content", "scene": "real scene (content-equal)"}

# Denoisers trained side by side (threads) by default: none. XLA's convolutions of one training
# already use both cores: a dim 8-frame burst (benchmarks/downstream_denoising.py --dim --seeds 0 1
# --steps 300) took 128 s one at a time and 159 s with 4 threads, the same PSNRs.
MAX_WORKERS = 1
MAX_STEPS = 3000          # the cap of the step-count selection (`choose_steps`)
PATIENCE = 3              # rounds of 100 steps without a gain of more than MIN_GAIN_DB end it
MIN_GAIN_DB = 0.02
PEAK_QUANTILE = 0.999     # PSNR peak: this quantile of the scene (mean of all frames), not the white level
# Below this gain of the best denoiser over the noisy input (dB), the scene leaves no room to rank noise
# models: the differences the check exists to show are of this size (issue 34's reference measurement on
# a real dim burst: UPI 1.4 dB behind real pairs), and a scene a denoiser cannot improve (texture at the
# scale of the noise) shows all rows at the noisy input's PSNR.
MIN_LEARNED_DB = 1.0


# ----------------------------------------------------------------------------- PSNR

def psnr(denoised, reference, reference_variance=0.0, peak: float = 1.0) -> float:
    """PSNR = 10 log10(peak^2 / MSE) (dB) of normalised planes against a noisy `reference` whose
    own noise variance (mean over pixels) is `reference_variance`: that variance is taken out of
    the mean squared error (see the module docstring). `peak` 1 is WhiteLevel - BlackLevel; the
    burst check uses the scene's PEAK_QUANTILE. NaN when the corrected error is not positive."""
    mse = float(np.mean((np.asarray(denoised, np.float64) - np.asarray(reference, np.float64)) ** 2))
    corrected = mse - float(reference_variance)
    return 10.0 * np.log10(peak * peak / corrected) if corrected > 0 else float("nan")


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
    """`psnr[(row, content)]`: mean PSNR (dB, corrected, on `peak`) over the test frames, one value
    per seed; `psnr_uncorrected` the same against the noisy reference as is; `noisy_psnr` the test
    frames themselves (no denoiser); `peak` the PSNR's peak (normalised: the scene's
    PEAK_QUANTILE); `noise` {row: description}; `frames`, `skipped`, `iso`, `folds`, `seeds`;
    `steps` Adam steps of every training, `step_curve` the validation errors (dB) of the selection
    that chose them (`choose_steps`; empty when `steps` was given); `cg_levels` how the CG content
    was brought to the burst's levels; `seconds` {row: training seconds per seed}."""

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
    peak: float = 1.0
    step_curve: tuple = ()
    cg_levels: str = ""

    def table(self) -> str:
        """A markdown table: rows x contents, mean +- sd over seeds (and the seeds' range)."""
        contents = [c for c in CONTENTS if any(k[1] == c for k in self.psnr)]
        lines = ["| noise model | " + " | ".join(CONTENT_NAMES[c] + " (dB)" for c in contents) + " |",
                 "|---|" + "---|" * len(contents)]
        for row in [r for r in ROWS if any(k[0] == r for k in self.psnr)]:
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

    def last_round_gain(self) -> float:
        """dB the real pairs' validation error gained in the last round of the step choice on the
        best of the rounds before it (what the patience rule weighs; 0 when the steps were given,
        inf with a single round)."""
        if not self.step_curve:
            return 0.0
        return min(self.step_curve[:-1]) - self.step_curve[-1] if len(self.step_curve) > 1 else float("inf")

    def learned(self, content: str = "scene") -> float:
        """dB the best row's mean PSNR on `content` lies above the noisy input (NaN without rows)."""
        means = [np.mean(v) for (row, c), v in self.psnr.items() if c == content and len(v)]
        return float(max(means) - self.noisy_psnr) if means else float("nan")

    def sentence(self) -> str:
        """The verdict in one sentence (`verdict_sentence`)."""
        return verdict_sentence(self)

    def summary(self) -> str:
        """The verdict, the table, the noise models and the protocol in a few lines."""
        noise = "\n".join(f"- {ROW_NAMES[r]}: {d}" for r, d in self.noise.items())
        skipped = "; ".join(f"{n}: {w}" for n, w in self.skipped) or "none"
        chosen = f"{self.steps} steps (as given)"
        if self.step_curve:
            chosen = (f"{self.steps} steps (chosen on a validation split of the burst: " +
                      ("real pairs' validation error converged)" if self.last_round_gain() <= MIN_GAIN_DB else
                       f"the cap, NOT converged: the validation error still gained {self.last_round_gain():.2f} dB "
                       f"in the last round)"))
        return (f"{self.sentence()}\n\n{len(self.frames)} frames at ISO {self.iso:g}, {self.folds} folds, seeds "
                f"{list(self.seeds)}, {chosen}, {self.cg_images} CG images{self.cg_levels}; PSNR peak = the "
                f"scene's {100 * PEAK_QUANTILE:g}th percentile ({self.peak:.4g} of WhiteLevel - BlackLevel), "
                f"the reference's own noise taken out\n\n{self.table()}\n\nnoise at ISO {self.iso:g}:\n{noise}\n"
                f"skipped files: {skipped}")


def compare_rows(a, b) -> str:
    """How PSNRs `a` beat `b` (one per seed each): "+x.xx dB" (or "-x.xx dB") when every seed of one
    lies above every seed of the other, "within training noise (+x.xx dB)" when the seeds' ranges
    overlap, "training noise not measured (one seed)" with fewer than two seeds in either."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    difference = float(a.mean() - b.mean())
    if a.size < 2 or b.size < 2:
        return f"{difference:+.2f} dB, training noise not measured (one seed)"
    if a.min() > b.max() or b.min() > a.max():
        return f"{difference:+.2f} dB"
    return f"within training noise ({difference:+.2f} dB)"


def verdict_sentence(result: DenoisingResult) -> str:
    """One sentence like the colour check's: the denoiser trained on g2r_jax's noise (fitted, else
    shipped) against real pairs and UPI, content-equal, then on the CG content; differences only
    where the seeds' ranges do not overlap."""
    ours = next((r for r in ("fitted", "shipped", "truth") if (r, "scene") in result.psnr or (r, "cg") in result.psnr),
                None)
    if ours is None:
        return "no g2r_jax row was trained."
    parts = []
    for content, others in (("scene", ("real", "upi")), ("cg", ("upi",))):
        if (ours, content) not in result.psnr:
            continue
        mine = result.psnr[(ours, content)]
        part = f"{CONTENT_NAMES[content]}: {ROW_NAMES[ours]} {np.mean(mine):.2f} dB"
        against = [f"{ROW_NAMES[o]} {np.mean(result.psnr[(o, content)]):.2f} ({compare_rows(mine, result.psnr[(o, content)])})"
                   for o in others if (o, content) in result.psnr]
        parts.append(part + (" against " + ", ".join(against) if against else ""))
    return (f"A denoiser trained on g2r_jax noise, tested on the burst's held-out frames (PSNR on the scene's "
            f"{100 * PEAK_QUANTILE:g}th percentile, {len(result.seeds)} seed(s), {result.steps} steps): "
            + "; ".join(parts) + f"; the noisy input is {result.noisy_psnr:.2f} dB." + _cannot_conclude(result))


def _cannot_conclude(result: DenoisingResult) -> str:
    """What keeps the rows from being ranked, if anything: training stopped at the cap before the
    real pairs converged (a row with more noise can lead only because it smooths faster), or a
    scene on which no denoiser gains MIN_LEARNED_DB over the noisy input."""
    reasons = []
    if result.last_round_gain() > MIN_GAIN_DB:
        reasons.append(f"training stopped at the cap of {result.steps} steps before the real pairs converged "
                       f"(their validation error still gained {result.last_round_gain():.2f} dB in the last round), "
                       f"so a row with more noise can lead only because it smooths faster")
    learned = result.learned("scene")
    if np.isfinite(learned) and learned < MIN_LEARNED_DB:
        reasons.append(f"no denoiser gains more than {max(learned, 0.0):.2f} dB over the noisy input on this scene "
                       f"(needed: {MIN_LEARNED_DB:g} dB), so it leaves no room to tell noise models apart (a smoother "
                       f"or defocused scene does)")
    if not reasons:
        return ""
    return " NO VERDICT on the noise models: " + "; and ".join(reasons) + "."


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


def match_levels(cg_planes: np.ndarray, scene: np.ndarray) -> np.ndarray:
    """CG planes (N, 4, h, w) brought to the burst's signal levels: each CG frame mapped by the
    affine x -> a x + b that sets its median and 99th percentile (over its four planes) to the
    scene's, clipped to [0, 1]. A dim scene then gets CG content of its own exposure instead of
    the profile's (whose white sits near 1). A flat frame is only scaled to the scene's median."""
    s50, s99 = np.quantile(np.asarray(scene, np.float64), [0.5, 0.99])
    out = np.empty_like(cg_planes)
    for k, planes in enumerate(np.asarray(cg_planes, np.float64)):
        c50, c99 = np.quantile(planes, [0.5, 0.99])
        if c99 - c50 > 1e-6:
            slope = (s99 - s50) / (c99 - c50)
            out[k] = np.clip(slope * (planes - c50) + s50, 0.0, 1.0)
        else:
            out[k] = np.clip(planes * (s50 / max(c50, 1e-6)), 0.0, 1.0)
    return out


def _validation_crops(burst: Burst, held, among, rng, patch: int = 64, per_frame: int = 8):
    """(noisy crops, reference crops) (V, 4, p, p) of the `held` frames against the mean of the
    other frames in `among`, at `per_frame` random places each."""
    _, _, h, w = burst.planes.shape
    p = min(patch, h, w)
    noisy, reference = [], []
    for i in held:
        others = burst.mean_of_others(i, among)
        for y, x in zip(rng.integers(0, h - p + 1, per_frame), rng.integers(0, w - p + 1, per_frame)):
            noisy.append(burst.planes[i, :, y:y + p, x:x + p])
            reference.append(others[:, y:y + p, x:x + p])
    return np.stack(noisy).astype(np.float32), np.stack(reference).astype(np.float32)


def choose_steps(key, burst: Burst, frames, gain: float, *, training: DenoiserTraining = DenoiserTraining(),
                 max_steps: int = MAX_STEPS) -> tuple[int, np.ndarray]:
    """(steps, validation curve in dB): how long the real-pairs row needs to converge, chosen on a
    validation split of the training `frames` (every fourth held out, at least one): real pairs
    trained on the rest, validated after every round against the mean of the other frames, until
    PATIENCE rounds in a row gain no more than MIN_GAIN_DB dB, at most `max_steps`; the steps of
    the best round."""
    frames = list(frames)
    held = frames[::4]
    train = [i for i in frames if i not in held]
    if len(train) < 2:
        raise ValueError(f"the burst's {len(frames)} training frames leave fewer than 2 to train real pairs "
                         f"beside a validation frame: give the number of steps instead")
    rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).tolist())
    validation = _validation_crops(burst, held, frames, rng)
    targets = np.stack([burst.mean_of_others(i, train) for i in train])
    fitted = train_denoiser(key, targets, inputs=burst.planes[train], gain=gain, steps=max_steps, training=training,
                            validation=validation, patience=PATIENCE, min_improvement=MIN_GAIN_DB)
    return int(fitted.best_round + 1) * training.steps_per_round, fitted.curve


def _train_row(key, burst: Burst, row: str, spec, content: str, train, cg_planes, gain: float, steps: int,
               training: DenoiserTraining):
    """The denoiser of one row on one content (see the module docstring)."""
    if content == "cg":
        noise_fn, noise_data = training_noise(spec, burst, 1.0)
        return train_denoiser(key, cg_planes, noise_fn=noise_fn, noise_data=noise_data, gain=gain, steps=steps,
                              training=training).model
    if row == "real":
        targets = np.stack([burst.mean_of_others(i, train) for i in train])
        return train_denoiser(key, targets, inputs=burst.planes[train], gain=gain, steps=steps,
                              training=training).model
    pairs = len(train) // 2    # two halves of equal size (an odd frame left out), so one noise factor fits both
    halves = (train[0:2 * pairs:2], train[1:2 * pairs:2])
    noise_fn, noise_data = training_noise(spec, burst, 1.0 - 1.0 / len(halves[0]))
    means = np.stack([burst.planes[half].mean(0) for half in halves])
    return train_denoiser(key, means[::-1], inputs=means, noise_fn=noise_fn, noise_data=noise_data,
                          gain=gain, steps=steps, training=training).model


@dataclasses.dataclass
class _Scoring:
    """What scoring a denoiser on the burst's frames needs, computed once per burst."""
    burst: Burst
    sums: tuple
    variance: list
    peak: float
    gain: float

    def reference(self, i):
        return (self.sums[0] - self.burst.planes[i]) / (self.burst.n - 1)

    def score(self, model, frames):
        """({frame: corrected PSNR}, {frame: uncorrected PSNR})."""
        corrected, raw = {}, {}
        for i in frames:
            denoised = denoise(model, self.burst.planes[i], self.gain)
            corrected[i] = psnr(denoised, self.reference(i), self.variance[i], self.peak)
            raw[i] = psnr(denoised, self.reference(i), 0.0, self.peak)
        return corrected, raw


def _check_arguments(burst, profile, rows, contents):
    if not isinstance(burst, Burst):
        burst = read_burst(burst)
    unknown = [r for r in rows if r not in ROWS] + [c for c in contents if c not in CONTENTS]
    if unknown:
        raise ValueError(f"unknown rows/contents {unknown}; rows are {ROWS}, contents {CONTENTS}")
    profile_cfa = tuple(int(c) for c in np.asarray(profile.cfa_pattern))
    if profile_cfa != burst.cfa_pattern:
        raise ValueError(f"the profile's CFA pattern {profile_cfa} is not the burst's {burst.cfa_pattern} "
                         f"({burst.names[0]}): a profile of another camera?")
    return burst


def run_burst_check(burst, profile, cg_images=(), *, rows=ROWS, contents=CONTENTS, seeds=(0, 1, 2), steps=None,
                    max_steps: int = MAX_STEPS, folds: int = 2, truth_noise=None, cg_count: int = 32,
                    training: DenoiserTraining = DenoiserTraining(), progress=None,
                    workers: int | None = None, cache=None) -> DenoisingResult:
    """The denoising check on a burst (a `Burst`, or a folder / list of DNGs for `read_burst`).

    **Arguments:** `profile` the camera's SensorProfile (its CFA pattern must be the burst's);
    `cg_images` paths or (H, W, 3) uint8 arrays (the first `cg_count`) for the `cg` content,
    brought to the burst's levels (`match_levels`); `rows` a subset of ROWS, `contents` of
    CONTENTS; `seeds`: each draws the networks' initialisation, crops, noise and the CG images'
    illuminants; one seed gives every row the same draws (a paired comparison); `steps` Adam
    steps per training, or None: chosen by `choose_steps` (at most `max_steps`); `folds` test
    folds of the frames (interleaved; at least 2 training frames each); `truth_noise` optional
    (shot (4,), read (4,)) for the `truth` row instead of photon transfer; `progress` a callable
    taking one line of text, or a `downstream.base.progress.Progress` (advanced per denoiser trained:
    `trainings(...)` of them); `workers`: denoisers trained side by side in threads (None: up
    to `MAX_WORKERS`, at most the CPU count; the PSNRs do not depend on it); `cache` a
    `downstream.base.cache.DownstreamCache` whose stored scores (and chosen step count) replace the
    trainings it holds (None: all trained). **Returns:** `DenoisingResult` (`.sentence()`, `.table()`,
    `.summary()`).
    """
    say = progress or (lambda line: None)
    burst = _check_arguments(burst, profile, rows, contents)
    synthetic = [r for r in rows if r != "real"]
    specs = {r: noise_spec(r, burst, profile, truth_noise) for r in synthetic}
    specs["real"] = None
    noise = {r: specs[r].description for r in synthetic}
    if "real" in rows:
        noise["real"] = "the burst's own frames (training folds)"
    test_folds = _folds(burst.n, folds)
    scene = burst.planes.mean(0)
    sums = frame_sums(burst)
    scoring = _Scoring(burst, sums, [reference_and_variance(burst, i, sums)[1] for i in range(burst.n)],
                       float(np.quantile(scene, PEAK_QUANTILE)), 0.5 / max(float(np.quantile(scene, 0.99)), 1e-4))
    noisy_psnr = float(np.mean([psnr(burst.planes[i], scoring.reference(i), scoring.variance[i], scoring.peak)
                                for i in range(burst.n)]))
    curve = ()
    cg = _load_cg(cg_images, cg_count) if "cg" in contents and synthetic else None
    unit = _unit_keys(burst, cg, profile, truth_noise=truth_noise, training=sorted(dataclasses.asdict(training).items()),
                      max_steps=max_steps, folds=folds) if cache is not None else None
    if steps is None:
        steps, curve = _chosen_steps(burst, test_folds, scoring, seeds, training, max_steps, cache, unit)
        say(f"steps: {steps} (validation error by round, dB: {' '.join(f'{e:.2f}' for e in curve)})")
        advance(progress, 1, "burst check: denoisers")
    results = {(r, c): [] for r in rows for c in contents if not (r == "real" and c == "cg")}
    uncorrected = {k: [] for k in results}
    seconds = {r: [] for r in rows}
    for seed in seeds:
        base = jax.random.PRNGKey(int(seed))
        cg_planes = None if cg is None else match_levels(clean_cg_planes(cg, profile, burst.iso, int(seed)), scene)
        jobs = [(row, content, k, tuple(test)) for row in rows for content in contents if (row, content) in results
                for k, test in enumerate([[]] if content == "cg" else test_folds)]

        def run(job):
            row, content, k, test = job
            started = time.perf_counter()
            key = None if unit is None else unit(row, content, k, test, int(seed), int(steps))
            got = _stored_scores(cache, key)
            if got is None:
                train = [i for i in range(burst.n) if i not in test]
                model = _train_row(jax.random.fold_in(base, 0 if content == "cg" else 1 + k), burst, row,
                                   specs[row], content, train, cg_planes, scoring.gain, steps, training)
                got = scoring.score(model, range(burst.n) if content == "cg" else test)
                _store_scores(cache, key, got)
            advance(progress, 1, f"burst check: seed {seed}, {row}, {content}")
            return got, time.perf_counter() - started

        with ThreadPoolExecutor(max(1, min(len(jobs), workers or min(MAX_WORKERS, os.cpu_count() or 1)))) as pool:
            done = dict(zip(jobs, pool.map(run, jobs)))   # the denoisers are independent: trained side by side
        _collect(seed, rows, results, uncorrected, seconds, done, say)
    return DenoisingResult(psnr=results, psnr_uncorrected=uncorrected, noisy_psnr=noisy_psnr, noise=noise,
                           frames=burst.names, skipped=burst.skipped, iso=burst.iso, folds=len(test_folds),
                           seeds=tuple(seeds), steps=int(steps), cg_images=0 if cg is None else len(cg),
                           seconds=seconds, peak=scoring.peak, step_curve=tuple(np.asarray(curve).tolist()),
                           cg_levels="" if cg is None else " (each brought to the scene's median and 99th "
                                                           "percentile by an affine map)")


def _unit_keys(burst: Burst, cg, profile, **options):
    """key(*parts) of one stored outcome of the burst check (`downstream.base.cache`): the code, the
    burst's frames, the CG images, the profile and the options."""
    from g2r_jax.downstream.base.cache import code_digest, key_of, profile_text

    base = key_of(code_digest(), "burst check", burst.planes, burst.iso, list(burst.names), None if cg is None else cg,
                  profile_text(profile), sorted(options.items(), key=str))
    return lambda *parts: key_of(base, *parts)


def _chosen_steps(burst, test_folds, scoring, seeds, training, max_steps, cache, unit) -> tuple:
    """`choose_steps` on the first fold's training frames, or its stored (steps, curve)."""
    key = None if unit is None else unit("steps", int(seeds[0]))
    stored = None if key is None else cache.get(key)
    if stored is not None:
        return int(stored["steps"]), tuple(stored["curve"].tolist())
    train0 = [i for i in range(burst.n) if i not in test_folds[0]]
    steps, curve = choose_steps(jax.random.PRNGKey(int(seeds[0])), burst, train0, scoring.gain,
                                training=training, max_steps=max_steps)
    if key is not None:
        cache.put(key, {"steps": np.asarray(steps), "curve": np.asarray(curve, np.float64)})
    return steps, curve


def _stored_scores(cache, key):
    """(corrected, raw) PSNR per frame stored under `key`, or None."""
    stored = None if key is None else cache.get(key)
    if stored is None:
        return None
    frames = [int(i) for i in stored["frames"]]
    return dict(zip(frames, stored["corrected"].tolist())), dict(zip(frames, stored["raw"].tolist()))


def _store_scores(cache, key, got) -> None:
    if key is not None:
        corrected, raw = got
        frames = sorted(corrected)
        cache.put(key, {"frames": np.asarray(frames, int), "corrected": np.asarray([corrected[i] for i in frames]),
                        "raw": np.asarray([raw[i] for i in frames])})


def _collect(seed, rows, results, uncorrected, seconds, done: dict, say) -> None:
    """One seed's trainings (`done`: (row, content, fold, test) -> ((corrected, raw) PSNR per
    frame, seconds)) into the mean PSNR per row and content, in the rows' order."""
    for row in rows:
        for content in [c for c in CONTENTS if (row, c) in results]:
            parts = [got for (r, c, _, _), (got, _) in done.items() if (r, c) == (row, content)]
            if not parts:
                continue
            results[(row, content)].append(float(np.mean([v for got in parts for v in got[0].values()])))
            uncorrected[(row, content)].append(float(np.mean([v for got in parts for v in got[1].values()])))
            say(f"seed {seed} {row:8s} {content:6s} {results[(row, content)][-1]:.2f} dB")
        seconds[row].append(sum(t for (r, *_), (_, t) in done.items() if r == row))


def trainings(n_frames: int, rows, contents, seeds, *, folds: int = 2, choose: bool = True) -> int:
    """How many denoisers `run_burst_check` trains on a burst of `n_frames` (its units of
    progress; `choose`: the step count is chosen, one training more)."""
    per_seed = sum(1 if content == "cg" else len(_folds(n_frames, folds))
                   for row in rows for content in contents if not (row == "real" and content == "cg"))
    return per_seed * len(seeds) + int(choose)


denoising_benchmark = run_burst_check
