"""The readout stage (`g2r_jax.sensor.readout`): the noise, banding and levels `unprocess` applies."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax import sensor
from g2r_jax.profile import schema as pm

BLACK = jnp.full(4, 64.0, jnp.float32)
WHITE = jnp.float32(1023.0)


def test_unprocess_reads_out_through_the_readout_stage():
    from g2r_jax.pipeline import batch_conditions, unprocess

    profile = pm.load_profile("s20fe_night")
    key, neutral = jax.random.PRNGKey(4), jnp.array([0.6, 1.0, 0.4])
    gray = jnp.asarray(np.random.default_rng(2).uniform(0.05, 0.9, (32, 48, 3)), jnp.float32)
    noisy, clean, meta = unprocess(key, gray, profile, iso=800.0, transfer="linear", neutral=neutral, effects=False,
                                   quantize=False, return_clean=True)
    black = sensor.per_position(profile.black_level, clean.shape)
    signal = (clean - black) / (profile.white_level - black)
    conditions = jax.tree_util.tree_map(lambda x: x[0], batch_conditions(key[None], profile, neutral=neutral[None],
                                                                         iso=800.0))
    keys = jnp.stack([conditions["noise_key"], conditions["readout_key"]])
    read_out = sensor.readout(keys, signal, profile.black_level, profile.white_level,
                              noise=sensor.noise_at_iso(profile.noise, meta["iso"]), quantize=False)
    assert float(jnp.std(noisy - clean)) > 1.0                      # noise of several DN ...
    np.testing.assert_allclose(np.asarray(read_out), np.asarray(noisy), atol=0.01)   # ... the same draws


def test_noise_variance_banding_and_levels():
    signal = jnp.full((256, 256), 0.2, jnp.float32)
    at_iso = sensor.ReadoutNoise(shot=jnp.full(4, 1e-3), read=jnp.full(4, 2e-5))
    keys = jax.random.split(jax.random.PRNGKey(0))
    digital = np.asarray(sensor.readout(keys, signal, BLACK, WHITE, noise=at_iso, quantize=False), np.float64)
    expected = (1e-3 * 0.2 + 2e-5) * (1023 - 64) ** 2
    assert np.var(digital) == pytest.approx(expected, rel=0.05)
    assert np.mean(digital) == pytest.approx(64 + 0.2 * 959, abs=0.2)

    banded = sensor.readout(keys, signal, BLACK, WHITE, effects=sensor.banding_effects(0.01, 0.0), quantize=False)
    rows = np.asarray(banded, np.float64).mean(axis=1)
    assert np.std(rows) == pytest.approx(0.01 * 959, rel=0.15)
    assert np.ptp(np.asarray(banded), axis=1).max() < 1e-3      # one offset per row, no column banding

    clipped = sensor.readout(keys, jnp.full((4, 4), 1.5, jnp.float32), BLACK, WHITE, noise=at_iso)
    assert clipped.dtype == jnp.uint16 and np.all(np.asarray(clipped) == 1023)


def test_readout_jits_and_vmaps_over_keys():
    signal = jnp.full((3, 16, 16), 0.1, jnp.float32)
    at_iso = sensor.ReadoutNoise(shot=jnp.full(4, 1e-3), read=jnp.full(4, 1e-5))
    keys = jax.vmap(jax.random.split)(jax.random.split(jax.random.PRNGKey(1), 3))
    effects = sensor.banding_effects(0.002, 0.003)
    run = jax.jit(jax.vmap(lambda k, s: sensor.readout(k, s, BLACK, WHITE, noise=at_iso, effects=effects)))
    batched = np.asarray(run(keys, signal))
    for i in range(3):
        single = sensor.readout(keys[i], signal[i], BLACK, WHITE, noise=at_iso, effects=effects)
        np.testing.assert_array_equal(batched[i], np.asarray(single))
    assert not np.array_equal(batched[0], batched[1])
