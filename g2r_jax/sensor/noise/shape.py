"""Optional shape of the simulated noise: a noise level function and a spatial correlation kernel.

Real raw files are not always the sensor's Poissonian-Gaussian noise: lossy raw compression
(VC-5 in GoPro's GPR, lossy DNG) and phones' raw denoising leave a noise whose variance is not
linear in the signal and which is correlated between neighbouring pixels. Two optional
components of `sensor.NoiseModel` describe it; the jitted noise stage (`sensor.add_noise`)
calls the functions here only when they are present, so profiles without them simulate exactly
as before.

- Noise level function: variance as a piecewise-linear function of the normalised signal x on a
  fixed knot grid, per ISO row and tile position (`level_knots` (K,), `level_variance`
  (N, 4, K)); used instead of shot * x + read. Held constant outside the knots.
- Correlation kernel: a 3 x 3 kernel per tile position (`correlation_kernel` (4, 3, 3)) applied
  within each CFA plane to the white normals, normalised to unit sum of squares so that the
  pixel variance stays what the level function (or shot * x + read) says. Spatially correlated
  Gaussian noise as white noise filtered by a kernel: e.g. Lebrun, Colom & Morel, "Multiscale
  image blind denoising", IEEE TIP 2015 (noise model of compressed and processed images).
- Correlation by level (optional, with a kernel): `correlation_knots` (M,) and
  `correlation_weight` (4, M) in [0, 1], the kernel's share w(x) at signal x, piecewise linear.
  A pixel's noise is filtered by (1 - w) delta + w k, renormalised to unit sum of squares: white
  (w = 0) where a camera leaves the noise alone, the kernel (w = 1) where it smooths it, e.g. a
  phone or a lossy raw codec that denoises only above a signal level. A denoiser that pulls a
  pixel towards its 3 x 3 same-colour mean by s is exactly the kernel (1 - s) delta + s / 9,
  and a blend of it with delta is again such a kernel.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def level_variance_at(iso, knots_variance):
    """(4, K) level-function variances at `iso`, linear in ISO between rows (as shot/read).

    `knots_variance` is the pair (iso (N,), variance (N, 4, K))."""
    isos, variance = knots_variance
    n, p, k = variance.shape
    flat = variance.reshape(n, p * k)
    return jax.vmap(lambda column: jnp.interp(iso, isos, column), in_axes=1)(flat).reshape(p, k)


def level_function_planes(planes, knots, variance):
    """Variance of every plane pixel (4, h, w): piecewise-linear in the signal per position."""
    return jax.vmap(lambda plane, values: jnp.interp(plane, knots, values))(planes, variance)


def normalised_kernel(kernel):
    """(4, 3, 3) kernels scaled to unit sum of squares (the filtered noise keeps unit variance)."""
    return kernel / jnp.sqrt(jnp.maximum(jnp.sum(kernel**2, axis=(1, 2), keepdims=True), 1e-30))


def blend_norm(weight, centre):
    """Sum of squares of (1 - w) delta + w k for a unit-norm kernel k of centre tap `centre`:
    w^2 + 2 w (1 - w) centre + (1 - w)^2 (the off-centre taps carry w^2 (1 - centre^2))."""
    return weight**2 + 2 * weight * (1 - weight) * centre + (1 - weight) ** 2


def correlated_normals(normal_at_counter, mosaic_shape, kernel, per_position, valid_shape=None, weight=None):
    """Normals of an (H, W) mosaic filtered within each CFA plane by its 3 x 3 kernel.

    Pixel (y, x) of tile position p gets sum_{i,j} k_p[i, j] n(y + 2(i - 1), x + 2(j - 1)), the
    neighbours taken in its own CFA plane with periodic wrap inside the image (so every output
    sums nine distinct draws: the same variance at the borders as inside). n(y, x) is the
    noise stream's draw at counter y * w + x (`normal_at_counter`), recomputed for each offset
    rather than shifted, so that with `valid_shape` (h, w) (a zero-padded mosaic) the image gets
    exactly the values it gets unpadded. `weight` (H, W) in [0, 1] (or None: 1): each pixel's
    share of the kernel, (1 - w) delta + w k, scaled back to unit variance (`blend_norm`)."""
    height, width = mosaic_shape
    h, w = (height, width) if valid_shape is None else valid_shape
    h, w = jnp.asarray(h, jnp.int32), jnp.asarray(w, jnp.int32)
    rows = jax.lax.broadcasted_iota(jnp.int32, mosaic_shape, 0)
    cols = jax.lax.broadcasted_iota(jnp.int32, mosaic_shape, 1)
    kernel = normalised_kernel(kernel)
    out = None
    for i in range(3):
        for j in range(3):
            r = jnp.remainder(rows + 2 * (i - 1), h)
            c = jnp.remainder(cols + 2 * (j - 1), w)
            draw = normal_at_counter((r * w + c).astype(jnp.uint32))
            term = per_position(kernel[:, i, j], mosaic_shape) * draw
            out = term if out is None else out + term
            if i == 1 and j == 1:
                own = draw
    if weight is None:
        return out
    centre = per_position(kernel[:, 1, 1], mosaic_shape)
    mixed = weight * out + (1 - weight) * own
    return mixed * jax.lax.rsqrt(jnp.maximum(blend_norm(weight, centre), 1e-12))
