"""The fine texture of the camera's scenes (issue 49): what CG frames lack at the scale where a
network sees a whole scene, measured from the camera's own files without labels, and added to
CG images as a random texture of the same statistics.

At 32 pixels across, the NUS cameras' scenes change by a median 20 % (in log) from one pixel to
the next, the CARLA frames by 4 % (docs/pages/validation/downstream_isp.md, "The CG frames'
texture"): game-engine surfaces are flat at that scale and meet at a few strong edges, real ones
(foliage, facades, ground) are textured everywhere. A neural ISP trained on the CG frames then never learns how the developer renders fine
detail, and errs most at edges.

The model: the 3 x 3 covariance C of the images' *log texture* at `grid` pixels across their
shorter side, t = log x - G_s * log x per channel (x the image area-averaged to that grid, each
channel over its peak; G_s a Gaussian blur of `HIGH_PASS_SIGMA` grid pixels, normalised over the
pixels away from missing ones (Knutsson and Westin's normalised convolution, CVPR 1993); a
high-pass in log, so invariant to the image's exposure and white balance), over those pixels. `add_texture` draws white
Gaussian noise on the same grid, high-passes it with the same blur, scales it to unit variance
(analytically: the sum of the squared high-pass kernel) and to covariance C (its Cholesky
factor), clips it to +-`LIMIT`, resizes it to the image (linear interpolation) and multiplies the
image by its exponential. A stationary Gaussian texture of the real files' covariance trained the
ISP as well as the real files' own texture did (Canon1DsMkIII, 3 seeds: 26.32 against 26.13 dB).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

TEXTURE_GRID = 32        # pixels across the image's shorter side at which the texture is measured and added
HIGH_PASS_SIGMA = 1.5    # the blur of the high-pass, in grid pixels
LIMIT = 1.5              # |log texture| at most (a factor of 4.5)
_OFFSET = 2e-3           # log(x / peak + offset): darks do not dominate the texture
_RADIUS = 6              # the blur kernel's half-width (4 sigma)


@dataclasses.dataclass(frozen=True)
class TextureModel:
    """The log-texture covariance (3, 3) of a camera's scenes at `grid` pixels across (see the
    module docstring); `files`: how many images it was measured on; `source`: where they came from."""

    covariance: tuple
    grid: int = TEXTURE_GRID
    files: int = 0
    source: str = ""

    def to_dict(self) -> dict:
        """JSON-ready. **Returns:** a dict."""
        return {"covariance": [[round(float(v), 6) for v in row] for row in self.covariance], "grid": self.grid,
                "files": self.files, "source": self.source}


def texture_from_dict(document: dict) -> TextureModel:
    """A `TextureModel` from `TextureModel.to_dict`'s form, checked.

    **Raises:** ValueError naming the field that is wrong."""
    covariance = np.asarray(document.get("covariance"), np.float64)
    if covariance.shape != (3, 3) or not np.all(np.isfinite(covariance)):
        raise ValueError("texture.covariance: expected a 3 x 3 matrix of numbers")
    if not np.allclose(covariance, covariance.T, atol=1e-6) or np.min(np.linalg.eigvalsh(covariance)) < -1e-6:
        raise ValueError("texture.covariance: expected a symmetric positive semi-definite matrix")
    grid = int(document.get("grid", TEXTURE_GRID))
    if grid < 8:
        raise ValueError(f"texture.grid: {grid} pixels across is too coarse (at least 8)")
    return TextureModel(covariance=tuple(map(tuple, covariance.tolist())), grid=grid,
                        files=int(document.get("files", 0)), source=str(document.get("source", "")))


def _kernel() -> np.ndarray:
    x = np.arange(-_RADIUS, _RADIUS + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / HIGH_PASS_SIGMA) ** 2)
    return k / k.sum()


def _area_average(image: np.ndarray, grid: int) -> np.ndarray:
    """(h, w, 3) -> (grid, round(grid w / h), 3) for h <= w (and the transpose otherwise): the
    image cropped to whole blocks and area-averaged."""
    h, w, _ = image.shape
    step = max(1, min(h, w) // grid)
    rows, cols = h // step, w // step
    return image[:rows * step, :cols * step].reshape(rows, step, cols, step, 3).mean((1, 3))


def texture_residuals(images, grid: int = TEXTURE_GRID) -> tuple:
    """(residuals, kept): each image's log texture t at `grid` pixels across its shorter side (module
    docstring; a list of (h_i, w_i, 3)), and the pixels it is measured on (neither missing, a
    channel 0 or less, as the NUS thumbnails' masked chart and clipped pixels, nor next to one).

    **Arguments:** `images`: linear images (N, H, W, 3) or a list, any RGB and exposure; `grid`.
    **Returns:** two lists of arrays (h, w, 3) float32 and (h, w) bool."""
    from scipy.ndimage import binary_dilation, convolve1d

    kernel = _kernel()
    residuals, kept = [], []
    for image in images:
        image = np.asarray(image, np.float64)
        if image.ndim != 3 or image.shape[-1] != 3 or min(image.shape[:2]) < grid:
            raise ValueError(f"a texture image must be (H, W, 3) with both sides at least {grid}, got {image.shape}")
        small = _area_average(image, grid)
        missing = binary_dilation(np.any(small <= 0, axis=-1), iterations=1)
        peak = np.max(np.where(missing[..., None], 0.0, small), axis=(0, 1))
        logs = np.log(np.maximum(small, 0) / np.where(peak > 0, peak, 1.0) + _OFFSET)
        valid = (~missing).astype(np.float64)[..., None]
        blur = lambda v: convolve1d(convolve1d(v, kernel, axis=0, mode="reflect"), kernel, axis=1, mode="reflect")
        blurred = blur(logs * valid) / np.maximum(blur(valid), 1e-12)      # the missing pixels' weight 0
        residuals.append(np.where(missing[..., None], 0.0, np.clip(logs - blurred, -LIMIT, LIMIT)).astype(np.float32))
        kept.append(~missing)
    return residuals, kept


def fit_texture(images, *, grid: int = TEXTURE_GRID, source: str = "") -> TextureModel:
    """The `TextureModel` of `images` (the camera's real files, e.g. their thumbnails in camera
    RGB: no label is needed): the covariance of their log texture over the measured pixels.

    **Raises:** ValueError when no image holds a measured pixel."""
    residuals, kept = texture_residuals(images, grid)
    pixels = np.concatenate([r[k] for r, k in zip(residuals, kept)]) if residuals else np.zeros((0, 3))
    if len(pixels) < 16:
        raise ValueError(f"texture: {len(pixels)} measured pixel(s) in {len(residuals)} image(s); at least 16 are needed")
    covariance = np.cov(pixels.T.astype(np.float64))
    return TextureModel(covariance=tuple(map(tuple, covariance.tolist())), grid=grid, files=len(residuals),
                        source=source)


def _blur(z):
    """Separable Gaussian blur (`_kernel`) of (..., h, w, 3) noise, wrapping at the edges."""
    k = jnp.asarray(_kernel(), jnp.float32)
    for axis in (-3, -2):
        z = sum(w * jnp.roll(z, shift, axis=axis) for shift, w in zip(range(-_RADIUS, _RADIUS + 1), k))
    return z


def _high_pass_sd() -> float:
    """The standard deviation of white unit noise after `z - blur(z)` (the sum of the squared kernel)."""
    k = _kernel()
    impulse = np.outer(k, k)
    impulse[_RADIUS, _RADIUS] -= 1.0
    return float(np.sqrt(np.sum(impulse ** 2)))


def _root(model: TextureModel) -> jax.Array:
    return jnp.asarray(np.linalg.cholesky(np.asarray(model.covariance) + 1e-9 * np.eye(3)), jnp.float32)


def _field(root, key, shape, grid: int):
    h, w = shape
    scale = grid / min(h, w)
    gh, gw = max(1, round(h * scale)), max(1, round(w * scale))
    z = jax.random.normal(key, (gh, gw, 3), jnp.float32)
    z = (z - _blur(z)) / _high_pass_sd()
    field = jnp.clip(z @ root.T, -LIMIT, LIMIT)
    return field if (gh, gw) == (h, w) else jax.image.resize(field, (h, w, 3), "linear")


def texture_field(model: TextureModel, key, shape) -> jax.Array:
    """One draw of the log texture for an image of `shape` (H, W) (module docstring): (H, W, 3) float32."""
    return _field(_root(model), key, (int(shape[0]), int(shape[1])), model.grid)


@functools.partial(jax.jit, static_argnames="grid")
def _textured_batch(root, images, key, grid: int):
    keys = jax.random.split(key, images.shape[0])
    fields = jax.vmap(lambda k: _field(root, k, images.shape[1:3], grid))(keys)
    return images * jnp.exp(fields)


def add_texture(model: TextureModel, images, key) -> jax.Array:
    """`images` (H, W, 3) or (N, H, W, 3), linear, times exp(one `texture_field` each), drawn from
    `key` (split into one key per image). Pure JAX, jitted once per image shape and grid (the
    covariance is an argument, so another camera's model compiles nothing new).

    **Returns:** float32 of the same shape."""
    x = jnp.asarray(images, jnp.float32)
    if x.ndim == 3:
        return x * jnp.exp(texture_field(model, key, x.shape[:2]))
    return _textured_batch(_root(model), x, key, grid=model.grid)
