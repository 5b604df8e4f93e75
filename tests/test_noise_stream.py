"""The noise stream (`g2r_jax.sensor.noise.stream`): exact layout/batch invariance, the
inverse-CDF transform against scipy's, and the statistics of the draws."""

import numpy as np


def test_mosaic_draws_are_the_flat_draws_padding_and_vmap_change_nothing():
    import jax

    from g2r_jax.sensor.noise import stream as sensor

    for key in (jax.random.PRNGKey(3), jax.random.key(4)):
        flat = np.asarray(jax.jit(lambda k: sensor.standard_normal(k, (12, 20)))(key))
        np.testing.assert_array_equal(np.asarray(jax.jit(lambda k: sensor.standard_normal_planes(k, (12, 20)))(key)), flat)
        padded = jax.jit(lambda k: sensor.standard_normal_planes(k, (16, 32), valid_shape=(12, 20)))(key)
        np.testing.assert_array_equal(np.asarray(padded)[:12, :20], flat)
    keys = jax.random.split(jax.random.PRNGKey(5), 3)
    batched = jax.jit(jax.vmap(lambda k: sensor.standard_normal(k, (8, 9))))(keys)
    single = jax.jit(lambda k: sensor.standard_normal(k, (8, 9)))
    for i in range(3):
        np.testing.assert_array_equal(np.asarray(batched[i]), np.asarray(single(keys[i])))
    assert sensor.standard_normal(jax.random.PRNGKey(0), (4,), np.float16).dtype == np.float16


def test_transform_matches_the_exact_normal_quantile():
    import jax.numpy as jnp
    from scipy.special import ndtri

    from g2r_jax.sensor.noise import stream as sensor

    mantissa = np.arange(0, 2**23, dtype=np.uint32)          # every value of v the stream can draw
    exact_negative = ndtri((mantissa.astype(np.float64) + 0.5) / 2**24)
    for sign in (0, 1):
        bits = (np.uint32(sign) << np.uint32(31)) | (mantissa << np.uint32(8)) | np.uint32(0xA5)  # low 8 bits unused
        ours = np.asarray(sensor._normal_from_bits(jnp.asarray(bits)), np.float64)
        exact = exact_negative * (-1 if sign else 1)
        assert np.max(np.abs(ours - exact)) < 1e-5
        assert np.all(np.sign(ours) == (1 if sign else -1))
    assert 5.4 < -ndtri(0.5 / 2**24) < 5.5     # the largest draw in magnitude


def test_quantile_polynomials_are_the_documented_fits():
    from g2r_jax.sensor.noise import stream as sensor

    quantile, log1p = sensor._quantile_coefficients()
    np.testing.assert_allclose(sensor._QUANTILE, quantile, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(sensor._LOG1P, log1p, rtol=1e-6, atol=1e-9)


def test_draws_are_standard_normal_and_uncorrelated_across_neighbours_and_keys():
    import jax
    from scipy import stats

    from g2r_jax.sensor.noise import stream as sensor

    shape = (1024, 1024)
    n = shape[0] * shape[1]
    base = jax.random.PRNGKey(11)
    draws = {i: np.asarray(sensor.standard_normal_planes(jax.random.fold_in(base, i), shape), np.float64)
             for i in range(3)}
    z = draws[0]
    assert abs(z.mean()) < 5 / np.sqrt(n)
    assert abs(z.var() - 1) < 5 * np.sqrt(2 / n)
    assert abs(stats.kurtosis(z.ravel())) < 5 * np.sqrt(24 / n)
    assert abs(stats.skew(z.ravel())) < 5 * np.sqrt(6 / n)
    assert abs(np.mean(np.abs(z) > 3) - 2 * stats.norm.sf(3)) < 5 * np.sqrt(2 * stats.norm.sf(3) / n)
    assert stats.kstest(z.ravel()[::16], "norm").pvalue > 1e-3

    def correlation(a, b):
        return np.corrcoef(a.ravel(), b.ravel())[0, 1]

    bound = 5 / np.sqrt(n)
    for a, b in ((z[:, 1:], z[:, :-1]), (z[1:], z[:-1]), (z[2:], z[:-2]), (z[:, 2:], z[:, :-2]),
                 (z[1:, 1:], z[:-1, :-1]), (draws[0], draws[1]), (draws[1], draws[2])):
        assert abs(correlation(a, b)) < bound
        assert abs(correlation(a**2, b**2)) < bound * np.sqrt(3)        # no shared variance either
    # Keys one apart in either word (not produced by split/fold_in, but the hash must not care).
    k0, k1 = (int(v) for v in np.asarray(jax.random.key_data(base)))
    for neighbour in ((k0 ^ 1, k1), (k0, k1 + 1), (k1, k0)):
        other = np.asarray(sensor.standard_normal_planes(np.array(neighbour, np.uint32), shape), np.float64)
        assert abs(correlation(z, other)) < bound
