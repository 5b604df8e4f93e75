"""The fine texture of the camera's scenes (`content.texture`, issue 49): measured without labels,
blind to exposure and white balance, drawn back with the covariance it measured, missing pixels
left out, bad models refused, and the ISP task's g2r_jax rows carry it."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from g2r_jax.content import texture


def _textured_images(count=6, side=64, sd=0.3, seed=0):
    """Smooth images times a known white log texture (per 2 x 2 block: one grid pixel at 32)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:side, 0:side] / side
    base = 0.2 + 0.3 * np.sin(3 * x + 2 * y)[..., None] * np.array([0.5, 0.4, 0.3]) + 0.3
    log_texture = rng.normal(0, sd, (count, side // 2, side // 2, 1)) * np.array([1.0, 1.0, 1.0])
    log_texture = np.repeat(np.repeat(log_texture, 2, 1), 2, 2)
    return (base[None] * np.exp(log_texture)).astype(np.float32)


def test_texture_is_blind_to_exposure_and_white_balance():
    images = _textured_images()
    a = texture.fit_texture(images)
    b = texture.fit_texture(images * np.array([0.2, 0.5, 0.9], np.float32))
    assert np.allclose(a.covariance, b.covariance, atol=1e-6)
    assert a.files == 6 and a.grid == texture.TEXTURE_GRID


def test_a_flat_image_has_no_texture_and_a_textured_one_has_it():
    flat = np.full((3, 64, 64, 3), 0.4, np.float32)
    assert np.allclose(texture.fit_texture(flat).covariance, 0.0, atol=1e-10)
    rough = texture.fit_texture(_textured_images(sd=0.3))
    variance = np.diag(rough.covariance)
    # white noise of sd 0.3, high-passed by (1 - blur): most of its variance stays
    assert np.all(variance > 0.5 * 0.09) and np.all(variance < 0.09)
    assert np.allclose(np.corrcoef(np.asarray(rough.covariance))[0], 1.0, atol=0.05)


def test_missing_pixels_and_their_neighbours_are_left_out():
    images = _textured_images(sd=0.0)
    holed = images.copy()
    holed[:, 10:30, 10:30] = 0.0          # a masked chart: its edge would be a strong 'texture'
    assert np.allclose(texture.fit_texture(holed).covariance, texture.fit_texture(images).covariance, atol=1e-4)
    with pytest.raises(ValueError, match="measured pixel"):
        texture.fit_texture(np.zeros((1, 64, 64, 3), np.float32))


def test_a_draw_has_the_measured_covariance_and_keeps_the_shape():
    model = texture.fit_texture(_textured_images(count=8, seed=1))
    flat = np.full((300, 32, 32, 3), 0.25, np.float32)
    drawn = np.log(np.asarray(texture.add_texture(model, flat, jax.random.PRNGKey(0))) / 0.25)
    assert np.allclose(np.cov(drawn.reshape(-1, 3).T), model.covariance, rtol=0.1, atol=2e-3)
    frame = np.asarray(texture.add_texture(model, np.full((95, 160, 3), 0.25, np.float32), jax.random.PRNGKey(1)))
    assert frame.shape == (95, 160, 3) and np.all(np.isfinite(frame)) and np.all(frame > 0)
    again = np.asarray(texture.add_texture(model, flat[:4], jax.random.PRNGKey(0)))
    assert np.array_equal(again, np.asarray(texture.add_texture(model, flat[:4], jax.random.PRNGKey(0))))


def test_the_model_round_trips_and_bad_ones_are_refused():
    model = texture.fit_texture(_textured_images(), source="six images")
    back = texture.texture_from_dict(model.to_dict())
    assert np.allclose(back.covariance, model.covariance, atol=1e-6) and back.source == "six images"
    with pytest.raises(ValueError, match="3 x 3"):
        texture.texture_from_dict({"covariance": [[1, 0], [0, 1]]})
    with pytest.raises(ValueError, match="positive semi-definite"):
        texture.texture_from_dict({"covariance": [[1, 2, 0], [2, 1, 0], [0, 0, 1]]})
    with pytest.raises(ValueError, match="at least 32"):
        texture.fit_texture(np.ones((1, 16, 16, 3), np.float32))
