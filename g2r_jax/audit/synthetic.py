"""A synthetic camera and hidden-effect injection, for tests, benchmarks and self-checks.

`demo_profile` is a made-up 12-bit RGGB camera (colour matrices invented for the purpose, a
daylight illuminant population along its own CCT locus, a heteroscedastic noise model);
`inject` returns a copy of a profile with one effect of the audit vocabulary changed, which is
how a "measured" set with a known, hidden cause is produced.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from g2r_jax.illuminants import distributions as _illuminants
from g2r_jax.profile import schema as _profile
from g2r_jax import sensor as _sensor
from g2r_jax.colour.dng_model import DngColourModel
from g2r_jax.profile.schema import ProfileInfo, SensorProfile

# Invented XYZ -> camera matrices for Standard Light A (17) and D65 (21).
_CM_A = [[0.92, -0.36, -0.02], [-0.40, 1.16, 0.27], [-0.04, 0.12, 0.70]]
_CM_D65 = [[0.70, -0.18, -0.07], [-0.44, 1.20, 0.26], [-0.09, 0.18, 0.64]]


def demo_profile(*, seed: int = 0, n_illuminants: int = 40, dtype=np.float32) -> SensorProfile:
    """A 12-bit (black 256, white 4095) RGGB camera with a Gaussian illuminant model fitted to
    points scattered around its 3000-7000 K locus, exposure spread 0.25 stops, noise growing with
    ISO 100-800."""
    colour = DngColourModel.from_tags([17, 21], [_CM_A, _CM_D65], dtype=dtype)
    rng = np.random.default_rng(seed)
    locus = _illuminants.locus_chromaticities(colour, 64, cct_range=(3000.0, 7000.0))
    points = locus[rng.integers(0, len(locus), n_illuminants)] + rng.normal(0, 0.015, (n_illuminants, 2))
    illuminants = _illuminants.fit_gaussian(points, dtype=dtype)
    noise = _sensor.NoiseModel(
        iso=jnp.asarray([100.0, 800.0], dtype),
        shot=jnp.asarray([[1.2e-4] * 4, [9.6e-4] * 4], dtype),
        read=jnp.asarray([[2.0e-6] * 4, [1.6e-5] * 4], dtype),
        iso_range=jnp.asarray([100.0, 400.0], dtype))
    return SensorProfile(
        cfa_pattern=jnp.asarray([0, 1, 1, 2], jnp.int32),
        black_level=jnp.full(4, 256.0, dtype), white_level=jnp.asarray(4095.0, dtype),
        baseline_exposure=jnp.asarray(0.0, dtype), colour=colour, illuminants=illuminants,
        exposure=_sensor.ExposureModel(log2_mean=jnp.asarray(0.0, dtype), log2_std=jnp.asarray(0.25, dtype)),
        noise=noise, effects=_sensor.no_effects(dtype),
        info=ProfileInfo(name="demo", unique_camera_model="g2r_jax demo camera",
                         calibration_illuminants=(17, 21), provenance="synthetic (g2r_jax.audit.synthetic)"))


def levels_replaced(profile: SensorProfile, black: float, white: float) -> SensorProfile:
    """`profile` with another BlackLevel (every CFA position) and WhiteLevel, the noise model kept in
    normalised units: e.g. a NikonD5200-like camera of black 600, white 16383 (issue 29), whose
    shipped profile says 0 and 15892."""
    return _profile.replace(profile, black_level=jnp.full(4, float(black), profile.black_level.dtype),
                            white_level=jnp.asarray(float(white), profile.white_level.dtype))


def denoised_above(mosaic, info, level: float, strength: float) -> np.ndarray:
    """The raw of a camera that denoises in-camera above a signal level (phones, lossy raw
    codecs; issue 29): in each CFA plane, pixels whose 3 x 3 same-colour mean lies above `level`
    (fraction of the range above the BlackLevel tag) move towards that mean by `strength`
    (0: untouched, 1: replaced); rounded and clipped to [0, WhiteLevel] as a raw file is."""
    raw = np.asarray(mosaic, np.float64).copy()
    black = np.resize(np.asarray(info.black_level, np.float64).reshape(-1), 4)
    white = float(info.white_level)
    for p, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
        plane = raw[dy::2, dx::2]
        rows, cols = plane.shape
        padded = np.pad(plane, 1, mode="reflect")
        mean = np.zeros_like(plane)
        for a in range(3):
            for b in range(3):
                mean += padded[a:a + rows, b:b + cols] / 9.0
        pulled = (mean - black[p]) / (white - black[p]) > level
        plane[pulled] += strength * (mean[pulled] - plane[pulled])
    return np.clip(np.rint(raw), 0, white).astype(np.uint16)


def _effects(profile, **changes):
    return _profile.replace(profile, effects=_profile.replace(profile.effects, **changes))


def random_magnitude(cause: str, rng) -> dict:
    """A modest random magnitude for `cause` (a few percent of the range for offsets and gains,
    a few tenths of corner fall-off for shading), as the keyword arguments of `inject`."""
    sign = rng.choice([-1.0, 1.0])
    if cause == "black_level":
        return {"offset": float(rng.uniform(0.01, 0.03))}
    if cause == "white_level":
        return {"clip": float(rng.uniform(0.90, 0.97))}
    if cause == "green_imbalance":
        return {"ratio": float(1 + sign * rng.uniform(0.02, 0.05))}
    if cause == "lens_shading":
        return {"corner": float(rng.uniform(0.2, 0.4)), "colour": float(rng.uniform(0.0, 0.1))}
    if cause == "noise_model":
        return {"scale": float(rng.choice([rng.uniform(1.3, 1.7), rng.uniform(0.5, 0.7)]))}
    if cause == "banding":
        return {"std": float(rng.uniform(0.002, 0.004)), "axis": str(rng.choice(["row", "column"]))}
    if cause == "exposure_distribution":
        return {"stops": float(sign * rng.uniform(0.45, 0.75))}
    if cause == "defective_pixels":
        return {"count": int(rng.integers(10, 40)), "seed": int(rng.integers(1 << 30))}
    if cause == "illuminant_distribution":
        return {"shift": float(rng.uniform(0.08, 0.15)), "seed": int(rng.integers(1 << 30))}
    raise ValueError(f"unknown cause {cause!r}")


def inject(profile: SensorProfile, cause: str, *, height: int = 200, width: int = 300, **magnitude) -> SensorProfile:
    """The profile with one effect added (the "true camera" behind a measured set).

    Magnitudes: black_level `offset` (fraction of range, all positions); white_level `clip`;
    green_imbalance `ratio` (Gb / Gr); lens_shading `corner` fall-off (gain 1 - corner at the
    corners, red and blue differing by +-`colour`); noise_model `scale` (shot and read variance);
    banding `std` and `axis`; exposure_distribution `stops`; defective_pixels `count`;
    illuminant_distribution `shift` (a second lamp population, 40% of the files, offset by
    `shift` in (r/g, b/g) across the main axis of the profile's Gaussian, like lamps off the CCT locus).
    """
    effects = profile.effects
    dtype = effects.black_pedestal.dtype
    if cause == "black_level":
        span = float(profile.white_level) - np.asarray(profile.black_level)
        return _effects(profile, black_pedestal=jnp.asarray(magnitude["offset"] * span, dtype))
    if cause == "white_level":
        return _effects(profile, clip_level=jnp.asarray(magnitude["clip"], dtype))
    if cause == "green_imbalance":
        gain = np.ones(4)
        gain[int(np.flatnonzero(np.asarray(profile.cfa_pattern) == 1)[1])] = magnitude["ratio"]
        return _effects(profile, channel_gain=jnp.asarray(gain, dtype))
    if cause == "lens_shading":
        corner, colour = magnitude["corner"], magnitude.get("colour", 0.0)
        per_colour = {0: corner * (1 + colour), 1: corner, 2: corner * (1 - colour)}
        a1 = np.array([-per_colour[int(c)] for c in np.asarray(profile.cfa_pattern)])
        return _effects(profile, shading=jnp.asarray(np.stack([a1, np.zeros(4)], 1), dtype))
    if cause == "noise_model":
        noise = _profile.replace(profile.noise, shot=profile.noise.shot * magnitude["scale"],
                                 read=profile.noise.read * magnitude["scale"])
        return _profile.replace(profile, noise=noise)
    if cause == "banding":
        field = "row_noise_std" if magnitude["axis"] == "row" else "column_noise_std"
        return _effects(profile, **{field: jnp.asarray(magnitude["std"], dtype)})
    if cause == "exposure_distribution":
        exposure = _profile.replace(profile.exposure, log2_mean=profile.exposure.log2_mean + magnitude["stops"])
        return _profile.replace(profile, exposure=exposure)
    if cause == "defective_pixels":
        rng = np.random.default_rng(magnitude.get("seed", 0))
        count = magnitude["count"]
        flat = rng.choice(height * width, count, replace=False)
        values = np.where(rng.random(count) < 0.7, 1.0, 0.0)
        return _effects(profile, defect_rows=jnp.asarray(flat // width, jnp.int32),
                        defect_cols=jnp.asarray(flat % width, jnp.int32), defect_values=jnp.asarray(values, dtype))
    if cause == "illuminant_distribution":
        model = profile.illuminants
        means = np.asarray(model.means, np.float64)
        chol = np.asarray(model.cholesky, np.float64)
        cov = chol @ np.swapaxes(chol, -1, -2)
        weights = np.asarray(model.weights, np.float64) / np.sum(model.weights)
        # off the main direction of the whole population (for a locus model: across the locus;
        # its components are isotropic, so one component's axes say nothing)
        spread = np.cov(means.T, aweights=weights) if len(means) > 1 else np.zeros((2, 2))
        minor = np.linalg.eigh(spread + np.einsum("k,kij->ij", weights, cov))[1][:, 0]
        shifted = means + magnitude["shift"] * minor * np.sign(minor[0] or 1.0)
        # 60% of the files from the profile's own model (any number of components), 40% shifted
        weights = np.concatenate([0.6 * weights, 0.4 * weights])
        mixture = _illuminants._model(weights.tolist(), np.concatenate([means, shifted]), np.concatenate([cov, cov]),
                                      None, "mixture", False, dtype)
        return _profile.replace(profile, illuminants=mixture)
    raise ValueError(f"unknown cause {cause!r}")


# ----------------------------------------------------------------------------- colour charts

def single_matrix_profile(profile: SensorProfile) -> SensorProfile:
    """`profile` reduced to its D65 ColorMatrix (a camera whose DNG carries one matrix): the
    profile under audit in the chart experiments (`colour_matrix`)."""
    from g2r_jax.colour.chart_fit import with_colour

    codes = list(profile.info.calibration_illuminants)
    matrix = np.asarray(profile.colour.color_matrix[codes.index(21) if 21 in codes else -1], np.float64)
    return with_colour(profile, DngColourModel.from_tags((21,), [matrix]), (21,))


def perturbed_colour(profile: SensorProfile, rng, size: float = 0.12) -> SensorProfile:
    """The camera a chart set is "measured" from: the profile's first ColorMatrix with an error
    drawn at random, CM -> (I + size * N(0, 1)) CM, as its only (D65) matrix."""
    from g2r_jax.colour.chart_fit import with_colour

    matrix = np.asarray(profile.colour.color_matrix[0], np.float64)
    error = np.eye(3) + size * rng.normal(size=(3, 3))
    return with_colour(profile, DngColourModel.from_tags((21,), [error @ matrix]), (21,))


def simulated_charts(truth: SensorProfile, n: int, seed: int, noise: float = 0.01):
    """`n` ColorChecker images that the camera `truth` records (a `charts.ChartSet`):
    `unprocess_batch` on the chart's physical colours (unclipped linear sRGB, as the audit
    predicts them) with neutrals sampled from `truth`'s illuminant model, `noise` multiplicative
    noise per patch and channel, 3 % unusable (NaN) patches, 3 folds."""
    import jax

    from g2r_jax.colour import charts as _charts
    from g2r_jax.pipeline import simulate_patches

    rng = np.random.default_rng(seed)
    neutrals = np.asarray(_illuminants.sample_neutrals(jax.random.PRNGKey(seed), truth.illuminants, n), np.float64)
    patches = simulate_patches(truth, neutrals, _charts.chart_linear_srgb(), transfer="linear")
    patches = patches * (1 + noise * rng.normal(size=(n, 24, 3)))
    patches[rng.random((n, 24)) < 0.03] = np.nan
    return _charts.ChartSet([f"img{i:03d}" for i in range(n)], patches, neutrals / neutrals[:, 1:2],
                            _charts.assign_folds(n, 3, seed), source="synthetic")
