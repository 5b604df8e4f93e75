"""Scene-light chromaticity as (mired, Duv): a plane that carries between cameras.

A white's correlated colour temperature (here in mired, 10^6 / CCT, where equal steps are
roughly equal visual steps) and its Duv, the signed distance in CIE 1960 uv from the Planckian
locus along the locus normal, positive towards green (ANSI C78.377; Ohno, LEUKOS 10(1), 2014).
The Planckian locus is Krystek's rational approximation (J. Opt. Soc. Am. A 2(3), 1985; uv within
1e-4 of Planck's law from 1000 K to 15000 K), its normal from the rational function's derivative.
Forward (`mired_duv_to_xy`: JAX, jitted, differentiable; `mired_duv_to_xy_numpy`: float64 numpy)
and inverse (`xy_to_mired_duv`, numpy) use the same locus, so they invert each other.
Internally Duv is held x 1000 (`DUV_SCALE`) so both coordinates are of order 1-100.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

DUV_SCALE = 1000.0                           # stored coordinate = Duv x 1000
MIRED_RANGE = (1e6 / 15000.0, 1e6 / 1500.0)  # where Krystek's locus holds (and real lights lie)

_U = ((0.860117757, 1.54118254e-4, 1.28641212e-7), (1.0, 8.42420235e-4, 7.08145163e-7))
_V = ((0.317398726, 4.22806245e-5, 4.20481691e-8), (1.0, -2.89741816e-5, 1.61456053e-7))


def _rational(coefficients, t):
    """(value, d value / dt) of (a0 + a1 t + a2 t^2) / (b0 + b1 t + b2 t^2)."""
    (a0, a1, a2), (b0, b1, b2) = coefficients
    numerator, denominator = a0 + a1 * t + a2 * t**2, b0 + b1 * t + b2 * t**2
    slope = ((a1 + 2 * a2 * t) * denominator - numerator * (b1 + 2 * b2 * t)) / denominator**2
    return numerator / denominator, slope


def _locus_and_normal(mired, xp):
    """Planckian uv at `mired` and the unit normal there pointing to +v (the Duv > 0 side)."""
    t = 1e6 / mired
    (u, du), (v, dv) = _rational(_U, t), _rational(_V, t)
    normal = xp.stack([-dv, du], -1)   # perpendicular to the tangent (du, dv)/dT
    normal = normal * xp.sign(normal[..., 1:2]) / xp.linalg.norm(normal, axis=-1, keepdims=True)
    return xp.stack([u, v], -1), normal


def _to_xy(point, xp):
    uv, normal = _locus_and_normal(point[..., 0], xp)
    uv = uv + (point[..., 1:2] / DUV_SCALE) * normal
    u, v = uv[..., 0], uv[..., 1]
    denominator = 2 * u - 8 * v + 4
    return xp.stack([3 * u / denominator, 2 * v / denominator], -1)


@jax.jit
def mired_duv_to_xy(point):
    """(..., 2) points (mired, Duv x 1000) -> CIE 1931 xy (..., 2), JAX."""
    return _to_xy(jnp.asarray(point), jnp)


def mired_duv_to_xy_numpy(point) -> np.ndarray:
    """`mired_duv_to_xy` in float64 numpy (fit-time work, no compilation)."""
    return _to_xy(np.asarray(point, np.float64), np)


def xy_to_mired_duv(xy) -> np.ndarray:
    """CIE xy (N, 2) -> (mired, Duv x 1000) (N, 2), numpy: the nearest point of the same locus,
    found on a 0.1-mired grid over 40-1000 mired and refined three times by a factor of 10
    (to 1e-5 mired), then the signed distance along that point's normal."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    denominator = -2 * xy[:, 0] + 12 * xy[:, 1] + 3
    uv = np.stack([4 * xy[:, 0] / denominator, 6 * xy[:, 1] / denominator], -1)
    grid = np.linspace(40.0, 1000.0, 9601)
    locus = _locus_and_normal(grid, np)[0]
    mired = grid[np.argmin(((uv[:, None] - locus[None]) ** 2).sum(-1), 1)]
    for level in range(1, 4):
        fine = mired[:, None] + np.linspace(-1.0, 1.0, 201)[None] * 10.0 ** -level
        fine_locus = _locus_and_normal(fine, np)[0]
        mired = fine[np.arange(len(xy)), np.argmin(((uv[:, None] - fine_locus) ** 2).sum(-1), 1)]
    base, normal = _locus_and_normal(mired, np)
    return np.stack([mired, ((uv - base) * normal).sum(-1) * DUV_SCALE], -1)
