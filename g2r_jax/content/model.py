"""The content model: a transform of a CG image in scene-linear light (linear sRGB, before the
camera sees it) that brings its content statistics toward those of the camera's real scenes.

`apply(model, linear)` is pure JAX (jit, vmap, grad). Its parameters, each the identity at 1:
- `chroma_scale` s: every pixel's chroma scaled toward its luminance, x' = Y + s (x - Y), Y the
  luminance of linear sRGB (IEC 61966-2-1 Y row): a convex combination for s in [0, 1], so
  non-negative pixels stay non-negative and neutral pixels (and Y) are unchanged (the issue's
  lead; what it fixed was the frames' cast, see 'cast').
- `tone_power` p: x' = peak (x / peak)^p, the image's peak kept: p > 1 darkens the body under
  its highlights (more dynamic range below the peak), p < 1 brightens it.
- `cast_scale` c and `cast_target` t (family 'cast'): each image's grey-world cast moved toward
  the colour t (linear sRGB, luminance 1) by a von Kries gain per image,
  x'_k = x_k (Y_m t_k / m_k)^(1 - c), m the image's mean colour and Y_m its luminance: at c = 0
  the image's mean becomes Y_m t (t = (1, 1, 1): neutral, the grey-world white balance of
  Buchsbaum, J. Franklin Inst. 1980, applied to the CG frame). A CG frame's own white point (the
  render's sun, sky and tone mapping) is unknown, and its cast is not the light the camera
  simulation draws: the CARLA frames are all blue, and an estimator trained on them learns that
  bias (docs/pages/validation/content_model.md, "Finding 3"). t is fitted to the median cast of
  the camera's real files balanced by their as-shot neutrals (`fitting`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from g2r_jax.content.scene_statistics import LUMINANCE
from g2r_jax.content.scene_statistics import luminance as _luminance

FAMILIES = {
    "identity": "no change",
    "chroma": "chroma scaled toward luminance (s from the chroma spread)",
    "chroma_tone": "chroma scaled toward luminance, then a power on the brightness under the peak",
    "cast": "each image's grey-world cast moved to the real scenes' (c = 0: all the way)",
    "scenes": "each image's cast and brightness taken to those of one of the camera's scenes, drawn per image",
}
# The measurement's choice of c for 'cast' (finding 3 of the validation page: c = 0 trained the
# CNN better than 0.35 on the training folds' inner third): the CG frame's own cast all replaced.
CAST_KEPT = 0.0


class ContentModel(eqx.Module):
    """Parameters of the content transform (a pytree: a jit argument) and the family it was fitted
    as (static). Build with `fit_content_model`, `identity` or `content_from_dict`."""

    chroma_scale: Float[Array, ""]
    tone_power: Float[Array, ""]
    cast_scale: Float[Array, ""]
    cast_target: Float[Array, "3"]          # 'cast'; 'scenes': the median cast (`as_cast`)
    family: str = eqx.field(static=True, default="identity")
    source: str = eqx.field(static=True, default="")
    target: tuple = eqx.field(static=True, default=())   # ((statistic, real median), ...) it was fitted to
    apply_by_default: bool = eqx.field(static=True, default=False)   # conversion applies it unless told not to
    scene_casts: Any = None          # 'scenes': (K, 3) target colours, linear sRGB, luminance 1
    scene_brightness: Any = None     # 'scenes': (K,) target brightness (mean Y over the largest channel)
    texture: Any = eqx.field(static=True, default=None)   # `content.texture.TextureModel` of the files, or None


def content_model(chroma_scale: float = 1.0, tone_power: float = 1.0, *, cast_scale: float = 1.0,
                  cast_target=(1.0, 1.0, 1.0), family: str = "chroma", source: str = "",
                  target: dict | None = None, apply_by_default: bool = False, scene_casts=None,
                  scene_brightness=None, texture=None) -> ContentModel:
    """A `ContentModel` from its parameters (checked: s and c in [0, 1], p in [0.25, 4], t three
    positive numbers, scaled here to luminance 1; family 'scenes': `scene_casts` (K, 3) positive
    colours, each scaled to luminance 1, and `scene_brightness` (K,) in (0, 1], `scenes`; `texture`:
    the files' `content.texture.TextureModel`, carried for the pairs of a neural ISP, not applied
    by `apply`)."""
    if family not in FAMILIES:
        raise ValueError(f"unknown content family {family!r}; expected one of {', '.join(FAMILIES)}")
    if not (np.isfinite(chroma_scale) and 0.0 <= chroma_scale <= 1.0):
        raise ValueError(f"content chroma_scale {chroma_scale!r} must be in [0, 1] (1 = unchanged)")
    if not (np.isfinite(tone_power) and 0.25 <= tone_power <= 4.0):
        raise ValueError(f"content tone_power {tone_power!r} must be in [0.25, 4] (1 = unchanged)")
    if not (np.isfinite(cast_scale) and 0.0 <= cast_scale <= 1.0):
        raise ValueError(f"content cast_scale {cast_scale!r} must be in [0, 1] (1 = unchanged)")
    cast_target = np.asarray(cast_target, np.float64).reshape(-1)
    if cast_target.shape != (3,) or not (np.all(np.isfinite(cast_target)) and np.all(cast_target > 0)):
        raise ValueError(f"content cast_target {cast_target.tolist()!r} must be three positive numbers (linear sRGB)")
    cast_target = cast_target / float(cast_target @ LUMINANCE)
    scene_casts, scene_brightness = _scene_table(family, scene_casts, scene_brightness)
    return ContentModel(chroma_scale=jnp.float32(chroma_scale), tone_power=jnp.float32(tone_power),
                        cast_scale=jnp.float32(cast_scale), cast_target=jnp.asarray(cast_target, jnp.float32),
                        family=family,
                        source=source, target=tuple(sorted((target or {}).items())),
                        apply_by_default=bool(apply_by_default), scene_casts=scene_casts,
                        scene_brightness=scene_brightness, texture=texture)


def _scene_table(family: str, casts, brightness):
    """The checked 'scenes' table as float32 arrays (None, None for the other families)."""
    if family != "scenes":
        if casts is not None or brightness is not None:
            raise ValueError(f"a scenes table is for family 'scenes', not {family!r}")
        return None, None
    casts = np.asarray(casts, np.float64)
    brightness = np.asarray(brightness, np.float64).reshape(-1)
    if casts.ndim != 2 or casts.shape[1] != 3 or len(casts) == 0 or len(brightness) != len(casts):
        raise ValueError(f"content scene_casts (K, 3) and scene_brightness (K,) must match, got "
                         f"{casts.shape} and {brightness.shape}")
    if not (np.all(np.isfinite(casts)) and np.all(casts > 0)):
        raise ValueError("content scene_casts must be positive numbers (linear sRGB colours)")
    if not (np.all(np.isfinite(brightness)) and np.all((brightness > 0) & (brightness <= 1))):
        raise ValueError("content scene_brightness must be in (0, 1]")
    casts = casts / (casts @ LUMINANCE)[:, None]
    return jnp.asarray(casts, jnp.float32), jnp.asarray(brightness, jnp.float32)


def identity() -> ContentModel:
    """The model that changes nothing."""
    return content_model(1.0, 1.0, family="identity", source="identity")


def describe(model: ContentModel) -> str:
    """One line naming the family and the parameters it uses, for the commands' messages."""
    if model.family == "scenes":
        brightness = np.asarray(model.scene_brightness)
        count = int(dict(model.target).get("scenes", len(brightness)))
        plural = "" if count == 1 else "s"
        scenes = (f"scene{plural} drawn from the prior of real scenes" if dict(model.target).get("prior_draws")
                  else f"real scene{plural}")
        prior_scenes = int(dict(model.target).get("prior_scenes", 0))
        if prior_scenes:
            from g2r_jax.content.scenes import table_rows

            share = float(np.mean(table_rows(count + prior_scenes, len(brightness)) < count))
            scenes += f" ({share:.0%} of the draws) or {prior_scenes} of the prior of real scenes"
        return (f"scenes, each frame's cast and brightness those of one of {count} {scenes}, one picked at random per frame "
                f"(brightness {np.min(brightness):.2f}-{np.max(brightness):.2f}, median {np.median(brightness):.2f})")
    if model.family == "cast":
        r, g, b = (float(v) for v in model.cast_target)
        return (f"cast, each frame's mean colour taken {1 - float(model.cast_scale):.0%} of the way to "
                f"({r:.3f}, {g:.3f}, {b:.3f}) (linear sRGB)")
    words = f"{model.family}, chroma scale {float(model.chroma_scale):.2f}"
    return words + (f", tone power {float(model.tone_power):.2f}" if model.family == "chroma_tone" else "")


def as_cast(model: ContentModel) -> ContentModel:
    """The 'cast' model within `model`: itself for 'cast', the median cast of a 'scenes' model's
    table (its `cast_target`, what the 'cast' family fits to the same files); ValueError for the
    other families, which hold no cast."""
    if model.family == "cast":
        return model
    if model.family != "scenes":
        raise ValueError(f"the content model {model.family!r} holds no cast (only 'cast' and 'scenes' do)")
    return content_model(cast_scale=CAST_KEPT, cast_target=np.asarray(model.cast_target), family="cast",
                         source=f"{model.source} (its median cast only)",
                         target={k: v for k, v in model.target if k.startswith("cast_")},
                         apply_by_default=model.apply_by_default, texture=model.texture)


def with_default(model: ContentModel, apply_by_default: bool) -> ContentModel:
    """The same model with `apply_by_default` set."""
    return dataclasses.replace(model, apply_by_default=bool(apply_by_default))


def as_matrix(model: ContentModel, linear=None) -> Float[Array, "3 3"] | None:
    """The transform as a 3 x 3 matrix A on linear sRGB (x' = A x) when it is linear, else None.
    'identity' and 'chroma': A = s I + (1 - s) 1 w^T, w the luminance row (row i gives
    x'_i = s x_i + (1 - s) Y). 'cast': A = diag(gains) of one image, so it needs that image
    `linear` (H, W, 3), or its `mean_grid` (None without it); zero padding at its edges leaves the
    gains unchanged (they depend on the ratios of the channel means only). A colour stage that is
    itself a matrix on linear sRGB takes M A in place of M, so the model costs no pass over the
    pixels (`pipeline.content_stage`)."""
    if model.family in ("chroma_tone", "scenes"):
        return None
    if model.family == "cast":
        if linear is None:
            return None
        return jnp.diag(_cast_gains(jnp.asarray(linear, jnp.float32), model).reshape(3))
    s = jnp.asarray(model.chroma_scale, jnp.float32)
    if model.family == "identity":
        s = jnp.float32(1.0)
    weights = jnp.asarray(LUMINANCE, jnp.float32)
    return s * jnp.eye(3, dtype=jnp.float32) + (1.0 - s) * jnp.ones((3, 1), jnp.float32) * weights[None, :]


def scenes_split(model: ContentModel, draw, grid, count=None):
    """A 'scenes' model on one image as x' = f(x) A x: A (3, 3) the diagonal of the cast's gains
    and `tone`, the (peak, power) of the scalar f per pixel (`pixel_factor`), both found on the
    image's `mean_grid` (`scenes.scene_parameters`). A colour stage that is a matrix M on linear
    sRGB takes M A, and its mosaic the factor f of the image's pixels: `apply`'s result to float
    rounding, with no pass over the (H, W, 3) image. `count`: the grid's pixels that belong to a
    zero-padded image (`grid_count`)."""
    from g2r_jax.content.scenes import scene_parameters

    peak, power, gains = scene_parameters(model, draw, jnp.asarray(grid, jnp.float32), _gains_toward, count)
    return jnp.diag(gains.reshape(3)), (peak, power)


def pixel_factor(linear, tone):
    """The scalar f (H, W) per pixel of `scenes_split`'s split for the image `linear` (H, W, 3)."""
    from g2r_jax.content.scenes import tone_factor

    return tone_factor(linear, *tone)


def apply(model: ContentModel, linear: Float[Array, "*batch H W 3"], draw=None,
          grid=None, grid_count=None) -> Float[Array, "*batch H W 3"]:
    """The content transform of one image (H, W, 3) or a batch (..., H, W, 3) in linear sRGB
    (values >= 0). The identity model (and s = 1, p = 1) returns its input bit for bit; 'chroma'
    is one element-wise pass; 'chroma_tone' computes each image's peak and the power; 'cast' each
    image's mean colour and a gain per channel; 'scenes' (`scenes`) needs `draw` (...,), each
    image's uniform draw in [0, 1) that picks its scene, and takes its parameters from `grid`
    (the images' `mean_grid`, decoded apart by the pipeline; default: taken from `linear`) and,
    for an image zero-padded at its bottom and right, `grid_count`, how many of the grid's pixels
    belong to it (`grid_count`), so that the padding does not change its scene's parameters.

    **Returns:** float32, same shape, >= 0, each image's peak unchanged by the tone power."""
    x = jnp.asarray(linear, jnp.float32)
    if model.family == "identity":
        return x
    if model.family == "scenes":
        if draw is None:
            raise ValueError("the 'scenes' content family draws a scene per image: pass draw, uniform in [0, 1)")
        from g2r_jax.content.scenes import apply_scenes

        grid = mean_grid(x) if grid is None else jnp.asarray(grid, jnp.float32)
        return apply_scenes(model, x, draw, grid, _gains_toward, grid_count)
    if model.family == "cast":
        return x * _cast_gains(x, model)
    luminance = _luminance(x)
    s = jnp.asarray(model.chroma_scale, jnp.float32)
    x = x + (s - 1.0) * (x - luminance)                     # = Y + s (x - Y); exactly x at s = 1
    if model.family != "chroma_tone":                       # static: no power, no image-wide peak
        return x
    p = jnp.asarray(model.tone_power, jnp.float32)
    peak = jnp.max(x, axis=(-3, -2, -1), keepdims=True)
    safe_peak = jnp.where(peak > 0, peak, 1.0)
    toned = safe_peak * jnp.power(jnp.clip(x / safe_peak, 0.0, None), p)
    return jnp.where(p == 1.0, x, toned)


MEAN_GRID = 64   # the image's mean colour is taken over at least this many rows and columns of it


def mean_grid(x):
    """Every k-th row and column of an image (..., H, W, C), k = max(1, min(H, W) // MEAN_GRID):
    at least a 64 x 64 grid of its pixels (67 x 100 of a 1000 x 1500 frame), the pixels whose mean
    is the image's mean colour for the 'cast' family. A grid of a grid is itself. The pipeline
    decodes this grid apart from the image, so that the image is still decoded only in the
    channel each mosaic site keeps: the mean of every pixel made `unprocess` 3.8 times slower
    (docs/pages/validation/content_model.md)."""
    step = max(1, min(x.shape[-3], x.shape[-2]) // MEAN_GRID)
    return x[..., ::step, ::step, :]


def grid_count(shape, valid_shape):
    """How many pixels of the `mean_grid` of an image of `shape` (..., H, W, C) belong to its top-left
    `valid_shape` (h, w) (traced allowed): ceil(h / k) ceil(w / k), k the grid's step."""
    step = max(1, min(shape[-3], shape[-2]) // MEAN_GRID)
    h, w = valid_shape[..., 0], valid_shape[..., 1]
    return ((h + step - 1) // step) * ((w + step - 1) // step)


_LUMINANCE_2_15 = np.round(np.asarray(LUMINANCE) * 2 ** 15).astype(np.int32)   # sums to 2^15


def _image_mean(x):
    """Mean colour of `mean_grid(x)` (..., 1, 1, C) up to a positive factor (the cast gains use
    only ratios of the channel means), as int32 sums of the pixels in fixed point (count x 2^bits
    <= 2^30: exact). Exact, so that it does not depend on the order of the sum, which changes with
    the batch and its sharding over devices: a last-bit change of a gain moved a pixel by 1 DN
    between a batch converted whole and the same batch sharded."""
    grid = mean_grid(x)
    count = grid.shape[-3] * grid.shape[-2]
    bits = 30 - max(0, int(np.ceil(np.log2(count))))
    peak = jnp.max(jnp.abs(grid), axis=(-3, -2, -1), keepdims=True)
    peak = jnp.where(jnp.isfinite(peak) & (peak > 0), peak, 1.0)
    fixed = jnp.round(jnp.clip(grid / peak, -1.0, 1.0) * (2.0 ** bits)).astype(jnp.int32)
    return jnp.maximum(jnp.sum(fixed, axis=(-3, -2), keepdims=True), 0)


def _exact_luminance(sums):
    """Y of `_image_mean`'s int32 sums (..., 3) -> float32 (..., 1): the weighted sum in integers
    (weights `_LUMINANCE_2_15`, each sum split into 15-bit halves so that no product overflows),
    so that no product and sum can fuse differently in differently compiled programs; the two
    halves meet in one float addition."""
    weights = jnp.asarray(_LUMINANCE_2_15)
    high = jnp.sum((sums >> 15) * weights, axis=-1, keepdims=True)
    low = jnp.sum((sums & 0x7FFF) * weights, axis=-1, keepdims=True)
    return (high.astype(jnp.float32) * 2.0 ** 15 + low.astype(jnp.float32)) * 2.0 ** -15


def _gains_toward(x, target):
    """Y_m t_k / m_k per image (`_image_mean`, `_exact_luminance`) for targets t (..., 3) of
    images x (..., H, W, 3), shaped (..., 1, 1, 3) to multiply `x`; a channel whose mean is 0 keeps
    its gain 1. After the exact sums, one product and one quotient per channel: nothing whose
    rounding depends on how the program was compiled."""
    sums = _image_mean(x)
    mean = sums.astype(jnp.float32)
    wanted = _exact_luminance(sums) * jnp.asarray(target, jnp.float32)[..., None, None, :]
    return jnp.where(mean > 0, wanted / jnp.where(mean > 0, mean, 1.0), 1.0)


def _cast_gains(x, model: ContentModel):
    """(Y_m t_k / m_k)^(1 - c) per image (`_gains_toward`), shaped to multiply `x`."""
    ratio = _gains_toward(x, model.cast_target)
    kept = jnp.asarray(model.cast_scale, jnp.float32)
    # c = 0 (the default) takes the ratio itself: a power's last bit can differ between a program
    # vectorised over a batch and one of a single image.
    return jnp.where(kept == 0.0, ratio, jnp.power(ratio, 1.0 - kept))
