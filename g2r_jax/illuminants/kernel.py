"""A kernel density of measured scene lights, elongated along the Planckian locus, with the prior.

Real scene lights lie on a narrow, curved band along the daylight/Planckian locus, most of them in
a few clusters (daylight, shade, tungsten). A single Gaussian restricted to their convex hull fills
the inside of the curve, where no light lies; this model keeps the lights where they are:
- one Gaussian per measured light (a kernel density estimate, Parzen, Ann. Math. Stat. 33, 1962;
  Silverman, "Density Estimation", 1986, ch. 4), its covariance R diag(h_along^2, h_across^2) R^T
  with R the rotation to the camera's Planckian locus tangent at the light (`locus_tangents`);
- the two bandwidths chosen by leave-one-out likelihood cross-validation (Habbema, Hermans & van
  den Broek 1974; Silverman 1986, sec. 3.4.4) on a log grid; with fewer than `MIN_LIGHTS_FOR_CV`
  lights, `DEFAULT_BANDWIDTHS` (the median of the cross-validated bandwidths of the NUS cameras);
- blended with a prior model (the cross-camera prior mapped into this camera) as the posterior
  predictive of a Dirichlet process whose base measure is the prior (Ferguson, Ann. Stat. 1(2),
  1973; Escobar & West, JASA 90, 1995, eq. 4): n/(n + n0) on the n lights' kernels and
  n0/(n + n0) on the prior, with n0 = `PRIOR_PSEUDO_LIGHTS`. One light gives mostly the prior,
  a hundred lights almost only their own density.
The result is an ordinary Gaussian-mixture `IlluminantModel` (kind 'kernel'), sampled by the
shared, jit/vmap-able `distributions.sample_chromaticity` and stored in the profile like the others.
Fitting is numpy (profile-build time).
"""

from __future__ import annotations

import numpy as np

from g2r_jax.illuminants import distributions as _distributions

# Fewer lights: fixed bandwidths. A leave-one-out fit of a few points is noise: with 5 and 9 lights
# it put the few-light model farther from all of a camera's lights than the fixed bandwidths did,
# leave-one-dataset-out in both directions (energy distance, Gehler-Shi cameras with the NUS pool
# 0.0194 -> 0.0168 at 5 lights, 0.0162 -> 0.0140 at 9; NUS cameras with the Gehler-Shi pool
# 0.0250 -> 0.0166, 0.0195 -> 0.0131; docs validation/illuminant_models, "Making the default hold
# there"). From 10 lights 'auto' fits the kernel model, where it is kept.
MIN_LIGHTS_FOR_CV = 10
DEFAULT_BANDWIDTHS = (0.04, 0.015)   # (along, across) in r/g, b/g: the cross-validated bandwidths of 6 NUS cameras'
                                     # lights (117-268 each) are 0.036-0.05 along, 0.0115-0.016 across
PRIOR_PSEUDO_LIGHTS = 5.0        # n0: the prior counts as this many lights
BANDWIDTH_GRID = np.geomspace(1e-3, 0.3, 24)
_POSITIVE = np.array([[-1.0, 0.0, 1e-3], [0.0, -1.0, 1e-3]])   # r/g > 1e-3 and b/g > 1e-3


def prior_share(n: int, prior_lights: float = PRIOR_PSEUDO_LIGHTS) -> float:
    """The weight n0 / (n + n0) of the base measure (the prior, or the pooled lights) in the
    Dirichlet-process posterior predictive after n distinct lights (Escobar & West, JASA 90, 1995,
    eq. 4; Blackwell & MacQueen, Ann. Stat. 1(2), 1973): the blend `fit_kernel` makes, and the
    share `choice.LightShares` reports. 1 for n = 0: no light, only the base measure."""
    if n < 0 or not prior_lights > 0:
        raise ValueError(f"prior_share needs n >= 0 lights and n0 > 0 pseudo-lights; got {n}, {prior_lights}")
    return float(prior_lights) / (n + float(prior_lights))


def locus_tangents(points, locus) -> np.ndarray:
    """(N, 2) unit tangents of the polyline `locus` (M, 2), M >= 2, at its point nearest each of
    `points` (N, 2): the direction of the nearest segment, all oriented like locus[-1] - locus[0]."""
    points = np.asarray(points, np.float64).reshape(-1, 2)
    locus = np.asarray(locus, np.float64)
    start, segment = locus[:-1], np.diff(locus, axis=0)
    lengths2 = np.maximum((segment**2).sum(-1), 1e-30)
    t = np.clip(((points[:, None] - start[None]) * segment[None]).sum(-1) / lengths2, 0.0, 1.0)
    nearest = start[None] + t[..., None] * segment[None]
    index = np.argmin(((points[:, None] - nearest) ** 2).sum(-1), axis=1)
    tangent = segment[index]
    return tangent / np.linalg.norm(tangent, axis=-1, keepdims=True)


def kernel_covariances(tangents, along: float, across: float) -> np.ndarray:
    """(N, 2, 2) covariances R diag(along^2, across^2) R^T, R's first column the tangent."""
    tangents = np.asarray(tangents, np.float64)
    normals = np.stack([-tangents[:, 1], tangents[:, 0]], -1)
    return (along**2 * tangents[:, :, None] * tangents[:, None, :]
            + across**2 * normals[:, :, None] * normals[:, None, :])


def _along_across(points, tangents):
    """(N, N) offsets of light i from light j along and across light j's tangent."""
    difference = points[:, None] - points[None]                       # i - j
    normals = np.stack([-tangents[:, 1], tangents[:, 0]], -1)
    return (difference * tangents[None]).sum(-1), (difference * normals[None]).sum(-1)


def _leave_one_out(u, v, along, across):
    """Mean leave-one-out log density for arrays of bandwidths `along` (A, 1, 1), `across` (A, 1, 1)
    broadcast against the (N, N) offsets: shape (A,)."""
    n = u.shape[0]
    log_p = -0.5 * ((u / along) ** 2 + (v / across) ** 2) - np.log(2 * np.pi * along * across)
    log_p = np.where(np.eye(n, dtype=bool), -np.inf, log_p)
    peak = log_p.max(axis=-1, keepdims=True)
    log_sum = np.log(np.exp(log_p - peak).sum(-1)) + peak[..., 0]
    return log_sum.mean(-1) - np.log(n - 1)


def leave_one_out_log_likelihood(points, tangents, along: float, across: float) -> float:
    """Mean over the lights of the log density at each light of the kernels of all the others."""
    u, v = _along_across(np.asarray(points, np.float64), np.asarray(tangents, np.float64))
    return float(_leave_one_out(u, v, np.array([[[along]]]), np.array([[[across]]]))[0])


def choose_bandwidths(points, tangents) -> tuple[float, float]:
    """(along, across) maximising the leave-one-out likelihood over `BANDWIDTH_GRID` squared;
    `DEFAULT_BANDWIDTHS` for fewer than `MIN_LIGHTS_FOR_CV` distinct lights."""
    points = np.asarray(points, np.float64)
    if len(np.unique(np.round(points, 9), axis=0)) < MIN_LIGHTS_FOR_CV:
        return DEFAULT_BANDWIDTHS
    u, v = _along_across(points, np.asarray(tangents, np.float64))
    grid = BANDWIDTH_GRID[:, None, None]
    scores = np.stack([_leave_one_out(u, v, grid, np.full_like(grid, across)) for across in BANDWIDTH_GRID], 1)
    scores = np.where(np.isfinite(scores), scores, -np.inf)
    i, j = np.unravel_index(np.argmax(scores), scores.shape)
    return float(BANDWIDTH_GRID[i]), float(BANDWIDTH_GRID[j])


def fit_kernel(chromaticities, tangents, *, prior=None, prior_lights: float = PRIOR_PSEUDO_LIGHTS,
               bandwidths=None, weights=None, dtype=np.float32) -> _distributions.IlluminantModel:
    """The kernel model of the module docstring.

    **Arguments:** `chromaticities`: (N, 2) measured lights (r/g, b/g), N >= 1; `tangents`: (N, 2)
    the locus direction at each (`locus_tangents`); `prior`: an `IlluminantModel` to blend with
    weight prior_lights / (N + prior_lights) (None: the kernels alone); `bandwidths`: (along,
    across) instead of the cross-validated ones; `weights`: (N,) positive weights of the lights
    (None: equal); `dtype` of the model.

    **Returns:** an `IlluminantModel` of kind 'kernel'. Its sampler keeps draws inside the prior's
    support when every light lies inside it (else only r/g, b/g > 1e-3).
    """
    points = np.asarray(chromaticities, np.float64).reshape(-1, 2)
    tangents = np.asarray(tangents, np.float64).reshape(-1, 2)
    if len(points) == 0:
        raise ValueError("the kernel illuminant model needs at least one measured illuminant")
    if len(tangents) != len(points) or not np.all(np.isfinite(points)) or np.any(points <= 0):
        raise ValueError("the kernel illuminant model needs finite, positive (r/g, b/g) and one tangent per light")
    along, across = choose_bandwidths(points, tangents) if bandwidths is None else bandwidths
    weights = np.full(len(points), 1.0) if weights is None else np.asarray(weights, np.float64).reshape(-1)
    if len(weights) != len(points) or not np.all(weights > 0):
        raise ValueError("the kernel illuminant model needs one positive weight per light")
    weights = weights / weights.sum()
    means, covariances, hull = points, kernel_covariances(tangents, along, across), _POSITIVE
    if prior is not None:
        share = prior_share(len(points), prior_lights)
        prior_cholesky = np.asarray(prior.cholesky, np.float64)
        prior_hull = np.asarray(prior.hull, np.float64)
        weights = np.concatenate([(1 - share) * weights, share * np.asarray(prior.weights, np.float64)])
        means = np.concatenate([means, np.asarray(prior.means, np.float64)])
        covariances = np.concatenate([covariances, prior_cholesky @ np.swapaxes(prior_cholesky, -1, -2)])
        if prior.use_hull and np.all(_distributions.inside_hull(points, prior_hull)):
            hull = prior_hull
    return _distributions._model(weights, means, covariances, hull, "kernel", True, dtype)
