"""unprocess: CFA layout, noise statistics, vmap/jit consistency, highlights, transfers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax.profile import schema as pm
from g2r_jax.pipeline import unprocess, without_content


def with_cfa(profile, pattern):
    return pm.replace(profile, cfa_pattern=jnp.asarray(pm.parse_cfa(pattern), jnp.int32))


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_each_pixel_keeps_its_cfa_colour(pattern):
    profile = with_cfa(pm.load_profile("Canon600D"), pattern)
    red = np.zeros((4, 4, 3), np.float32)
    red[..., 0] = 0.5
    mosaic, _ = unprocess(jax.random.PRNGKey(0), jnp.asarray(red), profile, noise=False,
                          neutral=jnp.array([0.5, 1.0, 0.6]))
    signal = np.asarray(mosaic, float) - float(profile.black_level[0])
    tile = signal[:2, :2].reshape(-1)
    letters = np.array(list(pattern))
    assert tile[letters == "R"].min() > 3 * tile[letters == "B"].max()
    assert tile[letters == "R"].min() > tile[letters == "G"].max()


def test_noise_variance_follows_the_profile_model():
    profile = pm.load_profile("s20fe_night")
    gray = jnp.full((256, 256, 3), 0.3, jnp.float32)
    mosaic, meta = unprocess(jax.random.PRNGKey(3), gray, profile, iso=800.0, transfer="linear",
                             neutral=jnp.array([0.6, 1.0, 0.4]), quantize=False)
    clean, _ = unprocess(jax.random.PRNGKey(3), gray, profile, iso=800.0, transfer="linear", noise=False,
                         neutral=jnp.array([0.6, 1.0, 0.4]), quantize=False)
    span = float(profile.white_level - profile.black_level[0])
    noisy, clean = np.asarray(mosaic) / span, np.asarray(clean) / span
    black = float(profile.black_level[0]) / span
    for p, (dy, dx) in enumerate([(0, 0), (0, 1), (1, 0), (1, 1)]):
        x = clean[dy::2, dx::2] - black
        expected = float(meta["noise_shot"][p]) * x.mean() + float(meta["noise_read"][p])
        measured = np.var(noisy[dy::2, dx::2] - clean[dy::2, dx::2])
        assert measured == pytest.approx(expected, rel=0.08)


def test_vmap_under_jit_equals_one_image_at_a_time():
    profile = pm.load_profile("s20fe_night")
    images = jnp.asarray(np.random.default_rng(0).integers(0, 256, (3, 8, 10, 3)), jnp.uint8)
    keys = jax.random.split(jax.random.PRNGKey(5), 3)
    batched, meta = jax.jit(jax.vmap(lambda k, im: unprocess(k, im, profile)))(keys, images)
    for i in range(3):
        single, single_meta = unprocess(keys[i], images[i], profile)
        np.testing.assert_array_equal(np.asarray(batched[i]), np.asarray(single))
        np.testing.assert_allclose(meta["neutral"][i], single_meta["neutral"], rtol=1e-6)


def test_highlight_safe_gains_keep_white_neutral_and_can_be_switched_off():
    profile = without_content(pm.load_profile("Canon600D"))   # white in, white out: no CG content model
    white = jnp.ones((2, 2, 3), jnp.float32)
    neutral = jnp.array([0.5, 1.0, 0.7])
    args = dict(noise=False, neutral=neutral, quantize=False, exposure_gain=1.0)
    safe, _ = unprocess(jax.random.PRNGKey(0), white, profile, highlight_safe=True, **args)
    plain, _ = unprocess(jax.random.PRNGKey(0), white, profile, highlight_safe=False, **args)
    black = float(profile.black_level[0])
    span = float(profile.white_level) - black
    safe, plain = (np.asarray(safe) - black) / span, (np.asarray(plain) - black) / span
    np.testing.assert_allclose(safe, 1.0, atol=1e-4)            # all channels at the top: neutral in raw
    red, blue = (divmod(int(np.flatnonzero(np.asarray(profile.cfa_pattern) == c)[0]), 2) for c in (0, 2))
    np.testing.assert_allclose(plain[red], 0.5, atol=1e-4)      # R = white * r/g
    np.testing.assert_allclose(plain[blue], 0.7, atol=1e-4)     # B = white * b/g


def test_transfers_and_uint8_lookup_agree_with_float_decoding():
    profile = pm.load_profile("Canon600D")
    codes = np.random.default_rng(1).integers(0, 256, (6, 6, 3)).astype(np.uint8)
    key = jax.random.PRNGKey(0)
    from_uint8, _ = unprocess(key, jnp.asarray(codes), profile, noise=False, quantize=False)
    from_float, _ = unprocess(key, jnp.asarray(codes / 255.0, jnp.float32), profile, noise=False, quantize=False)
    np.testing.assert_allclose(np.asarray(from_uint8), np.asarray(from_float), rtol=1e-5)
    gamma, _ = unprocess(key, jnp.asarray(codes), profile, noise=False, quantize=False, transfer="gamma2.2")
    assert not np.allclose(np.asarray(gamma), np.asarray(from_uint8))


def test_odd_sizes_are_refused():
    with pytest.raises(ValueError, match="even"):
        unprocess(jax.random.PRNGKey(0), jnp.zeros((3, 4, 3)), pm.load_profile("Canon600D"))


def test_fixed_neutrals_need_no_illuminant_model():
    from g2r_jax.pipeline import unprocess_batch, without_illuminants

    profile = pm.load_profile("Canon600D")
    images = jnp.asarray(np.random.default_rng(1).integers(0, 256, (2, 8, 10, 3)), jnp.uint8)
    keys = jax.random.split(jax.random.PRNGKey(2), 2)
    neutrals = jnp.array([[0.5, 1.0, 0.6], [0.7, 1.0, 0.4]])
    full, full_meta = unprocess_batch(keys, images, profile, neutral=neutrals)
    bare, bare_meta = unprocess_batch(keys, images, without_illuminants(profile), neutral=neutrals)
    np.testing.assert_array_equal(np.asarray(bare), np.asarray(full))
    np.testing.assert_array_equal(np.asarray(bare_meta["neutral"]), np.asarray(full_meta["neutral"]))
    with pytest.raises(ValueError, match="no illuminant model"):
        unprocess(keys[0], images[0], without_illuminants(profile))


def test_a_second_eager_call_of_the_same_shape_compiles_nothing(caplog):
    """Outside `jax.jit`, the conditions' chunk loop and the scenes model's bisection loop compile
    once per shape (they compiled again on every call: 3.6 s and ~600 memory mappings each)."""
    import logging

    profile = pm.load_profile("NikonD40")            # shipped: a 'scenes' content model, applied by default
    image = jnp.asarray(np.random.default_rng(0).random((24, 32, 3)).astype(np.float32))
    first = unprocess(jax.random.PRNGKey(0), image, profile)
    with jax.log_compiles(True), caplog.at_level(logging.WARNING, logger="jax"):
        again = unprocess(jax.random.PRNGKey(0), image, profile)
    assert [r.getMessage()[:60] for r in caplog.records if r.getMessage().startswith("Compiling")] == []
    np.testing.assert_array_equal(np.asarray(first[0]), np.asarray(again[0]))
