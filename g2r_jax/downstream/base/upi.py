"""UPI, the baseline g2r_jax replaces: Brooks, Mildenhall, Xue, Chen, Sharlet, Barron,
"Unprocessing Images for Learned Raw Denoising", CVPR 2019, Sec. 3 and its appendix.

A camera-agnostic inverse ISP: a random camera colour matrix (a convex combination of four
cameras' XYZ -> camera matrices), random white-balance gains, the inverse of a smoothstep tone
curve and a 2.2 gamma, highlight-safe inverse gains, and its own noise prior. The illuminant a
UPI image is labelled with is the inverse of its white-balance gains: (1/red, 1, 1/blue).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

# Sec. 3.1 "Color correction": XYZ -> camera matrices of four cameras, as published.
XYZ_TO_CAMERAS = np.array([
    [[1.0234, -0.2969, -0.2266], [-0.5625, 1.6328, -0.0469], [-0.0703, 0.2188, 0.6406]],
    [[0.4913, -0.0541, -0.0202], [-0.613, 1.3513, 0.2906], [-0.1564, 0.2151, 0.7183]],
    [[0.838, -0.263, -0.0639], [-0.2887, 1.0725, 0.2496], [-0.0627, 0.1427, 0.5438]],
    [[0.6596, -0.2079, -0.0562], [-0.4782, 1.3016, 0.1933], [-0.097, 0.1581, 0.5181]],
])
# Sec. 3.1 "White balance and digital gain": gains drawn per image.
RED_GAIN = (1.9, 2.4)
BLUE_GAIN = (1.5, 1.9)
BRIGHTNESS_GAIN = (0.8, 0.1)      # 1 / Normal(mean, std)
# Sec. 3.2 "Shot and read noise": log shot ~ U(log 1e-4, log 1.2e-2), log read = 2.18 log shot
# + 1.20 + Normal(0, 0.26).
SHOT_RANGE = (1e-4, 1.2e-2)
READ_LINE = (2.18, 1.20, 0.26)
HIGHLIGHT_INFLECTION = 0.9


def random_camera_matrix(key):
    """linear sRGB -> camera RGB: a random convex mix of the four XYZ -> camera matrices times
    sRGB -> XYZ, each row normalised to sum 1 (white stays white before the gains)."""
    from g2r_jax.colour.conversions import MATRIX_SRGB_TO_XYZ

    weights = jax.random.uniform(key, (4,), minval=1e-8, maxval=1e8)
    xyz_to_camera = jnp.einsum("k,kij->ij", weights / weights.sum(), jnp.asarray(XYZ_TO_CAMERAS, jnp.float32))
    srgb_to_camera = xyz_to_camera @ jnp.asarray(MATRIX_SRGB_TO_XYZ, jnp.float32)
    return srgb_to_camera / srgb_to_camera.sum(1, keepdims=True)


def random_gains(key):
    """(brightness, red, blue) gains, each as the ISP would apply it."""
    k_brightness, k_red, k_blue = jax.random.split(key, 3)
    brightness = 1.0 / (BRIGHTNESS_GAIN[0] + BRIGHTNESS_GAIN[1] * jax.random.normal(k_brightness))
    red = jax.random.uniform(k_red, minval=RED_GAIN[0], maxval=RED_GAIN[1])
    blue = jax.random.uniform(k_blue, minval=BLUE_GAIN[0], maxval=BLUE_GAIN[1])
    return brightness, red, blue


def random_noise_levels(key):
    """(shot, read) variance coefficients: variance = shot * x + read, x in [0, 1]."""
    k_shot, k_read = jax.random.split(key)
    log_shot = jax.random.uniform(k_shot, minval=np.log(SHOT_RANGE[0]), maxval=np.log(SHOT_RANGE[1]))
    slope, intercept, scatter = READ_LINE
    log_read = slope * log_shot + intercept + scatter * jax.random.normal(k_read)
    return jnp.exp(log_shot), jnp.exp(log_read)


def inverse_smoothstep(image):
    """Undo the global tone curve 3x^2 - 2x^3."""
    image = jnp.clip(image, 0.0, 1.0)
    return 0.5 - jnp.sin(jnp.arcsin(1.0 - 2.0 * image) / 3.0)


def gamma_expansion(image):
    """Undo a 2.2 gamma."""
    return jnp.maximum(image, 1e-8) ** 2.2


def safe_invert_gains(image, brightness, red, blue):
    """Divide by the gains, easing them to 1 towards white so highlights are not dimmed."""
    gains = jnp.stack([1.0 / red, 1.0, 1.0 / blue]) / brightness
    gray = jnp.mean(image, axis=-1, keepdims=True)
    mask = (jnp.maximum(gray - HIGHLIGHT_INFLECTION, 0.0) / (1.0 - HIGHLIGHT_INFLECTION)) ** 2
    return image * jnp.maximum(mask + (1.0 - mask) * gains, gains)


def unprocess_rgb(key, image, *, noise: bool = True):
    """One sRGB image (H, W, 3) in [0, 1] -> (camera RGB (H, W, 3) in [0, 1], illuminant (3,)).

    The RGB is what UPI's RGGB mosaic holds per tile (its green sites share one value); noise is
    drawn per channel with UPI's model.
    """
    k_matrix, k_gains, k_levels, k_noise = jax.random.split(key, 4)
    srgb_to_camera = random_camera_matrix(k_matrix)
    brightness, red, blue = random_gains(k_gains)
    linear = gamma_expansion(inverse_smoothstep(image))
    camera = jnp.clip(safe_invert_gains(linear @ srgb_to_camera.T, brightness, red, blue), 0.0, 1.0)
    if noise:
        shot, read = random_noise_levels(k_levels)
        sigma = jnp.sqrt(jnp.maximum(camera * shot + read, 0.0))
        camera = jnp.clip(camera + sigma * jax.random.normal(k_noise, camera.shape), 0.0, 1.0)
    illuminant = jnp.stack([1.0 / red, 1.0, 1.0 / blue])
    return camera, illuminant
