"""Illuminant distributions in the sensor's chromaticity plane (r/g, b/g).

One representation covers every model: a Gaussian mixture, optionally restricted to the convex
hull of the measured illuminants by rejection.
- `gaussian`: one component fitted to the as-shot neutrals of a DNG set, rejection to their
  convex hull (Graphics2RAW, Seo et al. ICCV 2023, Sec. 3 eqs. 2-3; the published default).
- `mixture`: several components chosen by BIC (for populations of distinct lamp types).
- `locus`: the single-DNG model of the supplement (Sec. S3): the calibration illuminants mapped to
  sensor space through their own matrices, the CCT locus between them obtained by interpolating
  the matrices, and a narrow distribution around that locus.
Sampling is pure JAX (vmap over keys); fitting is numpy at profile-build time.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from g2r_jax.runtime.host_arrays import device_array

_CANDIDATES = 16  # rejection draws per sample; with the hull of the data holding most of the
                 # Gaussian's mass, P(all 16 outside) is negligible


class IlluminantModel(eqx.Module):
    """Gaussian mixture over (r/g, b/g), with an optional convex-hull constraint.

    `hull` rows (a, b, c) describe half-planes a*x + b*y + c <= 0 (all must hold).
    """

    weights: Float[Array, "K"]
    means: Float[Array, "K 2"]
    cholesky: Float[Array, "K 2 2"]
    hull: Float[Array, "M 3"]
    kind: str = eqx.field(static=True, default="gaussian")
    use_hull: bool = eqx.field(static=True, default=True)


def inside_hull(points, hull, slack: float = 1e-9):
    """True where (..., 2) points satisfy every half-plane of `hull`."""
    values = points @ hull[:, :2].T + hull[:, 2]
    return jnp.all(values <= slack, axis=-1)


def sample_chromaticity(key, model: IlluminantModel):
    """One (r/g, b/g) draw: mixture component, Gaussian, rejection to the hull.

    The component comes from one uniform against the cumulative weights. Without a hull one
    candidate is drawn; with one, a fixed number (`_CANDIDATES`) keeps shapes static for
    jit/vmap and the first inside is kept; if none lands inside, the first candidate's component
    mean is returned (it lies inside the hull of the data it was fitted to).
    """
    k_component, k_normal = jax.random.split(key)
    dtype = model.means.dtype
    count = _CANDIDATES if model.use_hull else 1
    cumulative = jnp.cumsum(model.weights) / jnp.sum(model.weights)
    uniform = jax.random.uniform(k_component, (count,), dtype)
    components = jnp.minimum(jnp.searchsorted(cumulative, uniform, side="right"), model.weights.shape[0] - 1)
    normal = jax.random.normal(k_normal, (count, 2), dtype)
    candidates = model.means[components] + jnp.einsum("nij,nj->ni", model.cholesky[components], normal)
    if not model.use_hull:
        return candidates[0]
    ok = inside_hull(candidates, model.hull)
    first = jnp.argmax(ok)
    fallback = model.means[components[0]]
    return jnp.where(jnp.any(ok), candidates[first], fallback)


def chromaticity_to_neutral(chromaticity):
    """(r/g, b/g) -> camera neutral (r/g, 1, b/g)."""
    chromaticity = jnp.asarray(chromaticity)
    return jnp.stack([chromaticity[..., 0], jnp.ones_like(chromaticity[..., 0]), chromaticity[..., 1]], -1)


def neutral_to_chromaticity(neutral):
    """Camera neutral (any scale) -> (r/g, b/g)."""
    neutral = np.asarray(neutral, np.float64)
    return np.stack([neutral[..., 0] / neutral[..., 1], neutral[..., 2] / neutral[..., 1]], -1)


@functools.partial(jax.jit, static_argnames="n")
def sample_neutrals(key, model: IlluminantModel, n: int):
    """`n` camera neutrals (n, 3) drawn independently (vmapped `sample_chromaticity`)."""
    keys = jax.random.split(key, n)
    return chromaticity_to_neutral(jax.vmap(lambda k: sample_chromaticity(k, model))(keys))


# ----------------------------------------------------------------------------- fitting (numpy)

def convex_hull_halfplanes(points: np.ndarray) -> np.ndarray:
    """Half-planes (a, b, c) of the convex hull of 2-D points (Qhull via scipy)."""
    from scipy.spatial import ConvexHull, QhullError

    points = np.asarray(points, np.float64)
    if len(points) < 3:
        raise ValueError(f"a convex hull needs at least 3 illuminants, got {len(points)}")
    try:
        return np.asarray(ConvexHull(points).equations)
    except QhullError as error:
        raise ValueError(f"illuminants are collinear or degenerate: {str(error).splitlines()[0]}") from None


def _model(weights, means, covariances, hull, kind, use_hull, dtype) -> IlluminantModel:
    dtype = jax.dtypes.canonicalize_dtype(dtype)  # float64 only inside an x64 context
    covariances = np.asarray(covariances, np.float64)
    jitter = 1e-10 * np.eye(2)
    cholesky = np.linalg.cholesky(covariances + jitter)
    hull = np.zeros((1, 3)) if hull is None else np.asarray(hull)
    return IlluminantModel(
        weights=device_array(np.asarray(weights) / np.sum(weights), dtype),
        means=device_array(means, dtype),
        cholesky=device_array(cholesky, dtype),
        hull=device_array(hull, dtype),
        kind=kind,
        use_hull=use_hull,
    )


def fit_gaussian(chromaticities, *, use_hull: bool = True, dtype=np.float32) -> IlluminantModel:
    """The published model: sample mean and covariance of (r/g, b/g), hull of the points."""
    points = np.asarray(chromaticities, np.float64)
    if len(points) < 3:
        raise ValueError(f"a Gaussian with a hull needs at least 3 illuminants, got {len(points)}")
    hull = convex_hull_halfplanes(points) if use_hull else None
    return _model([1.0], points.mean(0)[None], np.cov(points.T)[None], hull, "gaussian", use_hull, dtype)


def _gaussian_log_density(points, mean, covariance):
    difference = points - mean
    inverse = np.linalg.inv(covariance)
    mahalanobis = np.einsum("ni,ij,nj->n", difference, inverse, difference)
    return -0.5 * (mahalanobis + np.log(np.linalg.det(covariance)) + 2 * np.log(2 * np.pi))


def _em_mixture(points, k, rng, iterations=200, floor=1e-6):
    n = len(points)
    means = points[rng.choice(n, k, replace=False)]
    covariances = np.stack([np.cov(points.T) + floor * np.eye(2)] * k)
    weights = np.full(k, 1.0 / k)
    previous = -np.inf
    for _ in range(iterations):
        log_p = np.stack([np.log(weights[j]) + _gaussian_log_density(points, means[j], covariances[j])
                          for j in range(k)], 1)
        total = np.logaddexp.reduce(log_p, axis=1)
        responsibility = np.exp(log_p - total[:, None])
        counts = responsibility.sum(0) + 1e-12
        weights = counts / n
        means = (responsibility.T @ points) / counts[:, None]
        for j in range(k):
            difference = points - means[j]
            covariances[j] = (responsibility[:, j, None] * difference).T @ difference / counts[j]
            covariances[j] += floor * np.eye(2)
        log_likelihood = total.sum()
        if abs(log_likelihood - previous) < 1e-8 * abs(log_likelihood):
            break
        previous = log_likelihood
    return weights, means, covariances, log_likelihood


def mixture_log_likelihood(model: IlluminantModel, chromaticities) -> np.ndarray:
    """Per-point log density of the mixture, numpy. The hull is ignored: a point outside it gets
    a finite density although the hull-restricted sampler never produces it."""
    points = np.asarray(chromaticities, np.float64)
    weights = np.asarray(model.weights, np.float64)
    means = np.asarray(model.means, np.float64)
    chol = np.asarray(model.cholesky, np.float64)
    log_p = np.stack([np.log(weights[j]) + _gaussian_log_density(points, means[j], chol[j] @ chol[j].T)
                      for j in range(len(weights))], 1)
    return np.logaddexp.reduce(log_p, axis=1)


def fit_mixture(chromaticities, *, max_components: int = 4, use_hull: bool = True, seed: int = 0,
                restarts: int = 8, min_points: float = 5.0, dtype=np.float32) -> IlluminantModel:
    """Gaussian mixture by EM, the number of components chosen by BIC (Schwarz 1978).

    A fit where any component explains fewer than `min_points` illuminants is rejected (a
    component on a handful of points is a degenerate spike, not a lamp population).
    """
    points = np.asarray(chromaticities, np.float64)
    rng = np.random.default_rng(seed)
    best = None
    for k in range(1, max(1, min(max_components, int(len(points) // min_points))) + 1):
        fits = [_em_mixture(points, k, rng) for _ in range(restarts if k > 1 else 1)]
        fits = [f for f in fits if k == 1 or np.min(f[0]) * len(points) >= min_points]
        if not fits:
            continue
        weights, means, covariances, log_likelihood = max(fits, key=lambda f: f[3])
        parameters = k * 5 + (k - 1)
        bic = parameters * np.log(len(points)) - 2 * log_likelihood
        if best is None or bic < best[0]:
            best = (bic, weights, means, covariances)
    _, weights, means, covariances = best
    hull = convex_hull_halfplanes(points) if use_hull else None
    kind = "mixture" if len(weights) > 1 else "gaussian"
    return _model(weights, means, covariances, hull, kind, use_hull, dtype)


def locus_chromaticities(colour_model, n_points: int = 32, cct_range=None) -> np.ndarray:
    """The CCT locus in sensor space (supplement S3): for CCTs evenly spaced in mired between
    the calibration illuminants (or `cct_range`), the camera neutral of that white under the
    matrices interpolated for it. Returns (n_points, 2) chromaticities (r/g, b/g)."""
    from g2r_jax.colour import conversions as _colour
    from g2r_jax.colour import dng_model as _dng
    from g2r_jax.runtime.x64 import enable_x64

    ccts = np.asarray(colour_model.calibration_cct, np.float64)   # ascending
    low, high = (ccts[0], ccts[-1]) if cct_range is None else np.asarray(cct_range, np.float64)
    if np.isclose(low, high):
        low, high = 2850.0, 6500.0  # one calibration illuminant: span tungsten to daylight
    ccts = 1e6 / np.linspace(1e6 / low, 1e6 / high, n_points)
    xys = _colour.CCT_to_xy(ccts)
    with enable_x64():
        model64 = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float64) if eqx.is_array(a) else a, colour_model)
        neutrals = np.asarray(jax.vmap(lambda xy: _dng.xy_to_camera_neutral(xy, model64))(jnp.asarray(xys)))
    return neutral_to_chromaticity(neutrals)


def fit_locus(colour_model, *, n_points: int = 32, spread: float = 0.05, cct_range=None,
              dtype=np.float32) -> IlluminantModel:
    """Single-DNG model (supplement S3): equal-weight components centred on the locus points,
    each isotropic with standard deviation `spread` times the locus length, i.e. a band along
    the locus from the lower to the higher calibration CCT."""
    points = locus_chromaticities(colour_model, n_points, cct_range)
    length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    sigma = max(spread * length, 1e-3)
    covariances = np.stack([sigma**2 * np.eye(2)] * n_points)
    return _model(np.ones(n_points), points, covariances, None, "locus", False, dtype)


def energy_distance(a, b) -> float:
    """Energy distance between two 2-D samples (Szekely & Rizzo 2013, eq. 2):
    2 E|X-Y| - E|X-X'| - E|Y-Y'|."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    cross = np.linalg.norm(a[:, None] - b[None], axis=-1).mean()
    within_a = np.linalg.norm(a[:, None] - a[None], axis=-1).mean()
    within_b = np.linalg.norm(b[:, None] - b[None], axis=-1).mean()
    return float(2 * cross - within_a - within_b)
