"""The noise stream: standard normal draws as a pure function of (key, element index)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


# ----------------------------------------------------------------------------- fast normal draws
#
# The noise stream. Each pixel's normal is a pure function of (key, counter), the counter being
# the element's flat index, so draws do not depend on batching, sharding or padding:
#   bits   = mix32(mix32(counter ^ k0) + k1)          (k0, k1: the key's two 32-bit words)
#   v      = ((bits >> 8 & 0x7FFFFF) + 1/2) / 2**24   (23 bits: a probability in (0, 1/2))
#   normal = -Q(v) if the top bit is set else Q(v)    (Q: the standard normal quantile, < 0)
# mix32 is Wellons' "lowbias32" integer hash (two xorshift-multiply rounds; hash-prospector,
# github.com/skeeto/hash-prospector). Q is a polynomial in t = sqrt(-ln v), on which the normal
# quantile is smooth over the whole range (the variable of the tail approximations of Wichura,
# "Algorithm AS 241", Applied Statistics 37, 1988): degree 11 in t rescaled to [-1, 1], a least-
# squares Chebyshev fit to scipy's `ndtri` at 400,001 points geometric in v over [2**-25, 1/2]
# (`_quantile_coefficients` refits it; error < 7e-6 at every one of the 2**23 values of v, tails
# to |z| = 5.42). ln v comes from the float's exponent and a degree-7 polynomial of its mantissa
# (the same kind of fit to log1p on [0, 1], error < 6e-7), so the draw is a few dozen vectorised
# float operations, no look-up and no library call: XLA fuses it into the pixel loop. History:
# `jax.random.normal` (Threefry + erfinv, 4.5x the rest of the pipeline on CPU), then a
# 1537-entry quantile table (its gather kept noise at 1.66x noise off on 2 CPU cores), now this;
# each change altered the noisy outputs of a given seed.

_MIX_MULTIPLIERS = (0x21F0AAAD, 0x735A2D97)      # lowbias32 (Wellons, hash-prospector)
_T_RANGE = (0.8325546111576977, 4.162773055788489)   # sqrt(ln 2), sqrt(25 ln 2): t over v in [2**-25, 1/2]
# Q(v) = sum_i QUANTILE[i] * s**i, s = (2 t - t0 - t1) / (t1 - t0); float32 values of the fit
_QUANTILE = (-2.8856353759765625, -2.6181082725524902, 0.12596362829208374, -0.06433083862066269,
             0.03363639488816261, -0.018324974924325943, 0.012453104369342327, -0.007107526995241642,
             -0.000465595192508772, 0.000331281014950946, 0.004052435979247093, -0.002448810962960124)
# ln(1 + f) = sum_i LOG1P[i] * x**i, x = 2 f - 1, f in [0, 1)
_LOG1P = (0.4054652452468872, 0.33333316445350647, -0.05556004121899605, 0.012348315678536892,
          -0.003062246832996607, 0.0008129912312142551, -0.0002688723034225404, 7.905407983344048e-05)


def _mix32(x):
    """lowbias32: a bijective 32-bit integer hash with near-ideal avalanche (Wellons)."""
    x = x ^ (x >> np.uint32(16))
    x = x * np.uint32(_MIX_MULTIPLIERS[0])
    x = x ^ (x >> np.uint32(15))
    x = x * np.uint32(_MIX_MULTIPLIERS[1])
    return x ^ (x >> np.uint32(15))


def _key_words(key):
    """The key as two uint32 words (k0, k1): Threefry keys are two words; longer key data (other
    `jax.random` implementations) is folded by xor into two."""
    data = jax.random.key_data(key) if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key) else key
    data = jnp.asarray(data).astype(jnp.uint32)
    if data.shape[-1] == 2:
        return data[..., 0], data[..., 1]
    words = data.reshape(data.shape[:-1] + (-1, 2))
    folded = jax.lax.reduce(words, np.uint32(0), jax.lax.bitwise_xor, (words.ndim - 2,))
    return folded[..., 0], folded[..., 1]


def _counter_bits(key, counter):
    """32 random bits for each uint32 `counter` under `key`."""
    k0, k1 = _key_words(key)
    return _mix32(_mix32(counter ^ k0) + k1)


def _quantile_coefficients(degree: int = 11, log_degree: int = 7):
    """Refit the two polynomials above (float64): the fits that `_QUANTILE` and `_LOG1P` hold."""
    from numpy.polynomial import chebyshev
    from scipy.special import ndtri

    v = np.geomspace(2.0**-25, 0.5, 400_001)
    t0, t1 = _T_RANGE
    s = (2 * np.sqrt(-np.log(v)) - t0 - t1) / (t1 - t0)
    quantile = chebyshev.cheb2poly(chebyshev.chebfit(s, ndtri(v), degree))
    f = np.linspace(0.0, 1.0, 100_001)
    log1p = chebyshev.cheb2poly(chebyshev.chebfit(2 * f - 1, np.log1p(f), log_degree))
    return quantile, log1p


def _polynomial(coefficients, x):
    """sum_i coefficients[i] * x**i by Estrin's scheme (pairs, then pairs of pairs): a dependency
    chain of log2(degree) multiply-adds instead of Horner's degree, so the long fused pixel loop
    is not bound by its latency (Knuth, TAOCP vol. 2, 4.6.4)."""
    terms = [np.float32(c) + np.float32(d) * x for c, d in zip(coefficients[0::2], coefficients[1::2])]
    if len(coefficients) % 2:
        terms.append(jnp.full_like(x, coefficients[-1]))
    power = x
    while len(terms) > 1:
        power = power * power
        terms = [terms[i] + power * terms[i + 1] if i + 1 < len(terms) else terms[i] for i in range(0, len(terms), 2)]
    return terms[0]


def _quantile_of_mantissa(mantissa):
    """Q(v), v = (mantissa + 1/2) / 2**24, for int32 `mantissa` in [0, 2**23): float32, < 0."""
    w = mantissa.astype(jnp.float32) + np.float32(0.5)                  # exact: 24 bits
    w_bits = jax.lax.bitcast_convert_type(w, jnp.int32)
    exponent = ((w_bits >> 23) - 127).astype(jnp.float32)
    fraction = jax.lax.bitcast_convert_type((w_bits & 0x7FFFFF) | 0x3F800000, jnp.float32)   # in [1, 2)
    ln_w = exponent * np.float32(np.log(2.0)) + _polynomial(_LOG1P, np.float32(2.0) * fraction - np.float32(3.0))
    t = jnp.sqrt(np.float32(24 * np.log(2.0)) - ln_w)                   # sqrt(-ln v)
    t0, t1 = _T_RANGE
    s = (np.float32(2.0) * t - np.float32(t0 + t1)) * np.float32(1.0 / (t1 - t0))
    return _polynomial(_QUANTILE, s)


def _normal_from_bits(bits):
    """Standard normal float32 from 32 random bits (see the stream above)."""
    mantissa = ((bits >> np.uint32(8)) & np.uint32(0x7FFFFF)).astype(jnp.int32)
    quantile = _quantile_of_mantissa(mantissa)
    return jnp.where((bits >> np.uint32(31)) == np.uint32(1), -quantile, quantile)


def _normal_from_counter(key, counter):
    """The stream's standard normal (float32) at uint32 `counter` under `key`."""
    return _normal_from_bits(_counter_bits(key, counter))


def _check_count(count: int) -> None:
    if count >= 2**32:
        raise ValueError(f"{count} draws exceed the 2**32 counters of one key; split the key")


def standard_normal(key, shape, dtype=jnp.float32):
    """Standard normal draws of `shape`: element i (flat, C order) is the stream's draw at
    counter i under `key` (see the stream above), computed in float32 and cast to `dtype`.

    Element-wise, so under jit it fuses with its consumer; vmap over keys gives each key its own
    draws, identical to drawing key by key."""
    shape = tuple(shape)
    count = int(np.prod(shape))
    _check_count(count)
    counter = jax.lax.iota(jnp.uint32, count).reshape(shape)
    return _normal_from_counter(key, counter).astype(dtype)


def standard_normal_planes(key, mosaic_shape, dtype=jnp.float32, *, valid_shape=None):
    """The noise draws of an (H, W) mosaic: pixel (y, x) takes the stream's draw at counter
    y * W + x, i.e. `standard_normal(key, (H, W), dtype)`; the name stays from the time the
    draws were made in the CFA planes layout.

    With `valid_shape` (h, w) (ints or traced), the counter is y * w + x: the top-left h x w of a
    larger mosaic gets exactly the draws of an h x w mosaic (for zero-padded batches)."""
    _check_count(int(np.prod(mosaic_shape)))
    width = mosaic_shape[1] if valid_shape is None else valid_shape[1]
    rows = jax.lax.broadcasted_iota(jnp.uint32, mosaic_shape, 0)
    cols = jax.lax.broadcasted_iota(jnp.uint32, mosaic_shape, 1)
    counter = rows * jnp.asarray(width).astype(jnp.uint32) + cols
    return _normal_from_counter(key, counter).astype(dtype)
