"""Training sets for the illuminant estimators: (thumbnails (N, 64, 64, 3), illuminants (N, 3)).

Each row of the downstream table is one way to make them:
- `cg_views` + `upi_set`: UPI (Brooks et al. 2019) applied to CG views;
- `cg_views` + `g2r_set`: g2r_jax with a profile (shipped, fitted to lights, single DNG; the
  published recipe with `recipe='published'`);
- `real_to_linear_srgb` + `g2r_set(..., transfer='linear', neutrals=...)`: the controls, real
  images rendered to linear sRGB at their measured white by the profile's own DNG colour model
  (what a DNG renderer does) and made RAW again under their own light, another image's light, or
  lights drawn from the profile.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.downstream.base import thumbnails as _thumbnails
from g2r_jax.downstream.base import upi as _upi

VIEW_SIZE = 128          # a view's side in pixels: its RAW mosaic bins to one 64 x 64 thumbnail
VIEW_SCALE = (0.5, 1.0)  # a view's side as a fraction of the image's shorter side
BATCH = 250              # images per compiled call (a fixed shape: one program whatever the set size)


def linear_images(images) -> list[np.ndarray]:
    """sRGB-coded images (uint8 or float in [0, 1]) -> linear float32 (IEC 61966-2-1)."""
    from g2r_jax.colour.conversions import srgb_decode_lut, srgb_to_linear

    table = srgb_decode_lut("srgb")
    out = []
    for image in images:
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[-1] != 3:
            raise ValueError(f"expected (H, W, 3) images, got {image.shape}")
        out.append(table[image] if image.dtype == np.uint8
                   else np.asarray(srgb_to_linear(np.clip(image.astype(np.float32), 0, 1)), np.float32))
    return out


def cg_views(linear: list[np.ndarray], n: int, seed: int, *, size: int = VIEW_SIZE,
             scale=VIEW_SCALE) -> np.ndarray:
    """`n` random square views (n, size, size, 3) of linear images: an image drawn at random, a
    square of `scale` times its shorter side at a random place, area-averaged to `size`, flipped
    left-right half the time. Images smaller than `size` are refused."""
    rng = np.random.default_rng(seed)
    out = np.empty((n, size, size, 3), np.float32)
    for i in range(n):
        image = linear[rng.integers(len(linear))]
        h, w, _ = image.shape
        if min(h, w) < size:
            raise ValueError(f"a CG image of {h} x {w} is smaller than the {size} x {size} view")
        side = max(size, int(round(rng.uniform(*scale) * min(h, w))))
        y, x = rng.integers(0, h - side + 1), rng.integers(0, w - side + 1)
        view = _thumbnails.area_average(image[y:y + side, x:x + side], size)
        out[i] = view[:, ::-1] if rng.random() < 0.5 else view
    return out


def _batches(n: int):
    for start in range(0, n, BATCH):
        yield start, min(start + BATCH, n)


def _padded(x, count):
    """Pad the first axis of `x` (`count` rows) to BATCH with copies of its first row (fixed shapes)."""
    if len(x) == BATCH:
        return x
    return np.concatenate([x, np.repeat(x[:1], BATCH - count, axis=0)])


@jax.jit
def _upi_thumbnails(keys, images):
    rgb, illuminants = jax.vmap(_upi.unprocess_rgb)(keys, images)
    b, h, w, _ = rgb.shape
    blocks = rgb.reshape(b, h // 2, 2, w // 2, 2, 3).mean((2, 4))   # one CFA tile per RGB pixel
    reduced = _thumbnails._reduce(blocks, _thumbnails.SIZE)
    return _thumbnails._unit_max(reduced), illuminants


def upi_set(views_srgb: np.ndarray, seed: int):
    """UPI training set from sRGB-coded views in [0, 1] (n, 128, 128, 3): (thumbnails, illuminants).

    UPI takes display sRGB (it inverts its own tone curve and gamma): pass views re-encoded to
    sRGB, e.g. `linear_to_srgb_views`.
    """
    n = len(views_srgb)
    keys = np.asarray(jax.random.split(jax.random.PRNGKey(seed), n))
    thumbs, lights = [], []
    for start, stop in _batches(n):
        t, l = _upi_thumbnails(_padded(keys[start:stop], stop - start),
                               _padded(np.asarray(views_srgb[start:stop], np.float32), stop - start))
        thumbs.append(np.asarray(t)[: stop - start])
        lights.append(np.asarray(l)[: stop - start])
    return np.concatenate(thumbs), np.concatenate(lights)


def linear_to_srgb_views(views_linear: np.ndarray) -> np.ndarray:
    """Linear views -> sRGB-coded float32 in [0, 1] (IEC 61966-2-1, in numpy: a set of views is
    too large for an uncompiled JAX call)."""
    x = np.clip(np.asarray(views_linear, np.float32), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4, dtype=np.float32) - 0.055).astype(np.float32)


def _padded_model(model):
    """The same distribution with its arrays padded to a few fixed sizes (components of weight 0
    at the end up to a power of two, half-planes 0 x + 0 y - 1 <= 0 that always hold), so that fits to different
    folders share one compiled sampler."""
    from g2r_jax.runtime.host_arrays import device_array

    weights, means, cholesky, hull = (np.asarray(a) for a in (model.weights, model.means, model.cholesky, model.hull))
    k = max(8, 1 << (len(weights) - 1).bit_length())
    m = -(-len(hull) // 32) * 32
    pad = k - len(weights)
    padded = (np.r_[weights, np.zeros(pad, weights.dtype)],
              np.concatenate([means, np.repeat(means[:1], pad, 0)]),
              np.concatenate([cholesky, np.repeat(cholesky[:1], pad, 0)]),
              np.concatenate([hull, np.tile(np.array([[0.0, 0.0, -1.0]], hull.dtype), (m - len(hull), 1))]))
    return eqx.tree_at(lambda d: (d.weights, d.means, d.cholesky, d.hull), model,
                       tuple(device_array(a, a.dtype) for a in padded))


@eqx.filter_jit
def _g2r_thumbnails(keys, images, neutrals, profile, recipe, highlight_safe):
    from g2r_jax.pipeline import unprocess_batch

    mosaics, metadata = unprocess_batch(keys, images, profile, neutral=neutrals, recipe=recipe,
                                        transfer="linear", highlight_safe=highlight_safe, quantize=False)
    thumbs = _thumbnails.mosaic_thumbnails(mosaics, profile.cfa_pattern.reshape(-1), profile.black_level,
                                           profile.white_level)
    return thumbs, metadata["neutral"]


def g2r_set(views_linear: np.ndarray, profile, seed: int, *, neutrals=None, recipe: str = "dng",
            highlight_safe: bool | None = None):
    """g2r_jax training set: linear sRGB views (n, 128, 128, 3) made RAW with `profile` (its
    illuminants, exposure, noise and effects), binned to thumbnails; label = the drawn neutral.

    **Arguments:** `neutrals` (n, 3) fixes each view's light instead of drawing it (the controls);
    `recipe`: 'dng' or 'published' (which decodes sRGB codes with a 2.2 gamma: views are
    re-encoded to sRGB for it).
    **Returns:** (thumbnails (n, 64, 64, 3), illuminants (n, 3)).
    """
    images = np.asarray(views_linear, np.float32)
    if recipe == "published":   # the published code reads sRGB codes and decodes them with a 2.2 gamma
        images = linear_to_srgb_views(images)
    n = len(images)
    key_lights, key_images = jax.random.split(jax.random.PRNGKey(seed))
    if neutrals is None:
        from g2r_jax.illuminants.distributions import sample_neutrals

        neutrals = sample_neutrals(key_lights, _padded_model(profile.illuminants), n)
    neutrals = np.asarray(neutrals, np.float32)
    neutrals = neutrals / neutrals[:, 1:2]
    # The lights are drawn above: one compiled program serves every illuminant model.
    from g2r_jax.pipeline import without_illuminants

    profile = without_illuminants(profile)
    keys = np.asarray(jax.random.split(key_images, n))
    thumbs, lights = [], []
    for start, stop in _batches(n):
        fixed = _padded(neutrals[start:stop], stop - start)
        t, l = _g2r_thumbnails(_padded(keys[start:stop], stop - start), _padded(images[start:stop], stop - start),
                               fixed, profile, recipe, highlight_safe)
        thumbs.append(np.asarray(t)[: stop - start])
        lights.append(np.asarray(l)[: stop - start])
    return np.concatenate(thumbs), np.concatenate(lights)


@eqx.filter_jit
def _to_srgb_matrices(neutrals, profile):
    from g2r_jax.pipeline import matrix_conditions

    conditions = jax.vmap(lambda n: matrix_conditions(n, profile))(neutrals)
    return conditions["srgb_to_wb_camera"], neutrals / jnp.max(neutrals, axis=1, keepdims=True)


def real_to_linear_srgb(thumbnails: np.ndarray, illuminants: np.ndarray, profile, *, size: int = VIEW_SIZE):
    """Real camera-RGB thumbnails (N, 64, 64, 3) -> linear sRGB views (N, size, size, 3).

    Each is white-balanced by its measured illuminant and mapped to sRGB by the inverse of the
    profile's DNG transform for that white (what a DNG renderer does: DNG spec 1.6 ch. 6), scaled
    to a maximum of 1, clipped to [0, 1] as a render would be, and upsampled by repetition.
    """
    neutrals = np.asarray(illuminants, np.float32)
    neutrals = neutrals / neutrals[:, 1:2]
    parts = [_to_srgb_matrices(_padded(neutrals[a:b], b - a), profile) for a, b in _batches(len(neutrals))]
    matrices, gains = (np.concatenate([np.asarray(p[i], np.float64) for p in parts])[: len(neutrals)] for i in (0, 1))
    to_srgb = np.linalg.inv(matrices)
    linear = np.einsum("nij,nhwj->nhwi", to_srgb, thumbnails / gains[:, None, None, :])
    peak = np.maximum(linear.reshape(len(linear), -1).max(1), 1e-12)
    linear = np.clip(linear / peak[:, None, None, None], 0.0, 1.0).astype(np.float32)
    factor = size // thumbnails.shape[1]
    return np.repeat(np.repeat(linear, factor, axis=1), factor, axis=2)
