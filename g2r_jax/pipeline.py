"""The inverse ISP: a display-referred CG image -> a RAW mosaic of the profiled camera.

Each stage is one small pure function; `unprocess` reads top to bottom like the method
(Graphics2RAW, Seo et al. ICCV 2023, Sec. 3; stage names after Brooks et al., "Unprocessing
Images for Learned Raw Denoising", CVPR 2019). jit it, vmap it over images and keys, or use
`unprocess_batch` for a batch whose bytes do not depend on the batching; the profile is a pytree
and may be a jit argument. Under jit the pixel stages fuse into one vectorised loop per frame.

Colour is the exact inverse of a DNG renderer (DNG spec 1.6, chapter 6): a renderer maps camera
RGB to XYZ_D50 with CameraToXYZ_D50(xy) for the white xy of AsShotNeutral, then Bradford to D65 and
sRGB. We apply the inverse of that product for the sampled neutral, so rendering our DNG returns
the input colours (up to one global exposure scale).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax import content as _content
from g2r_jax import sensor as _sensor
from g2r_jax.colour import conversions as _colour
from g2r_jax.colour import dng_model as _dng
from g2r_jax.illuminants import distributions as _illuminants
from g2r_jax.colour.camera_rgb import (matrix_srgb_to_white_balanced_camera,
                                      matrix_srgb_to_white_balanced_camera_published, mosaic_camera_rgb,
                                      resolve_highlight_safe)


def decode(image, transfer: str):
    """Display values -> linear sRGB; 8-bit input goes through an exact 256-entry table."""
    if image.dtype == jnp.uint8:
        # One gather per channel: XLA vectorises these, not a gather on the (H, W, 3) array.
        table = jnp.asarray(_colour.srgb_decode_lut(transfer))
        return jnp.stack([table[image[..., c]] for c in range(image.shape[-1])], axis=-1)
    return _colour.decode_to_linear(image.astype(jnp.float32), transfer)


METADATA_KEYS = ("neutral", "xy", "cct", "iso", "exposure_gain", "noise_shot", "noise_read", "converged")


def matrix_conditions(neutral, profile, recipe: str = "dng"):
    """The matrix colour stage, steps 3-4: the DNG white point of the neutral, its CCT, and the
    inverse DNG colour transform for that white (or the published approximation)."""
    # 3. Its white point, by the DNG neutral -> xy fixed point, and its CCT.
    xy, converged = _dng.camera_neutral_to_xy(neutral, profile.colour, throw=False)
    cct = _colour.xy_to_CCT(xy)

    # 4. Colour space transform: linear sRGB -> white-balanced camera RGB for that white.
    if recipe == "published":
        srgb_to_wb_camera = matrix_srgb_to_white_balanced_camera_published(neutral, profile.colour)
    else:
        srgb_to_wb_camera = matrix_srgb_to_white_balanced_camera(xy, neutral, profile.colour)
    return {"neutral": neutral, "xy": xy, "cct": cct, "converged": converged, "srgb_to_wb_camera": srgb_to_wb_camera}


def matrix_mosaic(linear, conditions, cfa_pattern, highlight_safe: bool):
    """The matrix colour stage, step 5: one 3x3 and the neutral's gains, mosaicked."""
    return mosaic_camera_rgb(linear, conditions["srgb_to_wb_camera"], conditions["gains"], cfa_pattern, highlight_safe)


COLOUR_STAGES = {"matrix": (matrix_conditions, matrix_mosaic)}


def colour_stage(colour: str):
    """(conditions, mosaic) functions of a colour model: 'matrix' (the DNG matrices, default),
    'spectral' or 'spectral-jakob2019' (`g2r_jax.colour.spectral.stage`, siblings with the same shape)."""
    if colour in COLOUR_STAGES:
        return COLOUR_STAGES[colour]
    from g2r_jax.colour.spectral.stage import STAGES

    if colour in STAGES:
        return STAGES[colour]
    raise ValueError(f"unknown colour model {colour!r}; expected one of matrix, {', '.join(STAGES)}")


def _metadata(conditions, colour: str):
    extra = () if colour == "matrix" else ("illuminant_family", "illuminant_spectrum")
    return {k: conditions[k] for k in METADATA_KEYS + extra}


CONTENT_STREAM = 47   # `jax.random.fold_in` salt of the content model's per-image draw


def sample_conditions(key, profile, *, neutral=None, iso=None, exposure_gain=None, recipe: str = "dng",
                      colour: str = "matrix"):
    """Steps 2-4 of `unprocess` and its other per-image draws, without touching pixels.

    **Returns:** a dict of small arrays: the metadata of `unprocess` (`METADATA_KEYS`) plus what
    the colour stage's mosaic needs (`srgb_to_wb_camera` (3, 3)...), `gains` (3,) and the keys of
    the noise and readout draws.
    """
    k_illuminant, k_exposure, k_iso, k_noise, k_readout = jax.random.split(key, 5)
    dtype = jnp.float32

    # 2. Sample an illuminant from the camera's distribution: a camera neutral (r/g, 1, b/g).
    if neutral is None:
        if profile.illuminants is None:
            raise ValueError(f"profile {profile.info.name!r} has no illuminant model (`without_illuminants`): "
                             "give the lights as `neutral`")
        neutral = _illuminants.chromaticity_to_neutral(
            _illuminants.sample_chromaticity(k_illuminant, profile.illuminants))
    neutral = jnp.asarray(neutral, dtype)
    neutral = neutral / neutral[1]

    # 3-4. The colour stage: white point, CCT and the transform to white-balanced camera RGB.
    colour_conditions = colour_stage(colour)[0](neutral, profile, recipe)
    neutral = colour_conditions["neutral"]

    if exposure_gain is None:
        exposure_gain = _sensor.sample_exposure_gain(k_exposure, profile.exposure)
    iso = _sensor.sample_iso(k_iso, profile.noise) if iso is None else jnp.asarray(iso, dtype)
    shot, read = _sensor.noise_parameters(iso, profile.noise)
    conditions = {**colour_conditions, "iso": iso,
                  "exposure_gain": jnp.asarray(exposure_gain, dtype), "noise_shot": shot, "noise_read": read,
                  "noise_level": _sensor.noise_level_at(iso, profile.noise),
                  "gains": neutral / jnp.max(neutral), "noise_key": k_noise, "readout_key": k_readout}
    if getattr(getattr(profile, "content", None), "family", None) == "scenes":
        # the scene the content model draws for this image, from its own stream: the other draws
        # (and every conversion without this family) stay bit for bit as they were
        conditions["content_draw"] = jax.random.uniform(jax.random.fold_in(key, CONTENT_STREAM), (), dtype)
    return conditions


def render_mosaic(image, conditions, profile, *, transfer: str = "srgb", noise: bool = True,
                  effects: bool = True, highlight_safe: bool | None = None, recipe: str = "dng",
                  quantize: bool = True, lens_gain=None, colour: str = "matrix", valid_shape=None,
                  return_clean: bool = False, content: bool | None = None, return_scene: bool = False):
    """Steps 1 and 5-7 of `unprocess`: the pixels, for `conditions` from `sample_conditions`.

    Returns the mosaic, or with `return_clean` the pair (mosaic, clean): clean is the same
    mosaic without the random parts of the sensor (noise, row/column banding), every
    deterministic effect kept, from the same colour computation (one pass under jit). With
    `return_scene` the adapted scene (`adapted_scene`: linear sRGB after the content model, before
    the exposure gain) follows: (mosaic, scene) or (mosaic, clean, scene).

    `valid_shape`: (h, w) (traced int32 allowed) when `image` is an h x w image zero-padded at
    the bottom and right; the top-left h x w of the result is then bit for bit that of the
    unpadded image (shading centre, noise counters and banding follow the image's own size).

    Every stage is element-wise in the (H, W) mosaic layout, so under jit XLA fuses them into one
    loop from the input codes to the uint16 output, with no float64 and no intermediate arrays.
    """
    # 1. Decode display values to linear sRGB.
    curve = "gamma2.2" if recipe == "published" else transfer
    linear = decode(image, curve)
    grid = lambda: decode(_content.mean_grid(image), curve)
    count = None if valid_shape is None else _content.grid_count(image.shape, jnp.asarray(valid_shape))
    scene = adapted_scene(linear, profile, content, grid, conditions.get("content_draw"), count) if return_scene else None
    highlight_safe = resolve_highlight_safe(highlight_safe, recipe)
    linear, conditions = content_stage(linear, conditions, profile, content, colour, grid=grid,
                                       highlight_safe=highlight_safe, grid_count=count)

    # 5. Un-white-balance and mosaic in one step, scaled so that white reaches 1 in the
    #    strongest channel, then a global exposure gain.
    mosaic = colour_stage(colour)[1](linear, conditions, profile.cfa_pattern, highlight_safe)
    if "content_tone" in conditions:
        mosaic = mosaic * _content.pixel_factor(linear, conditions["content_tone"])
    mosaic = mosaic * conditions["exposure_gain"]

    # 6. Optics: shading and channel gains (and the renderer's lens-shading gain taken out).
    if effects:
        mosaic = _sensor.apply_optical_effects(mosaic, profile.effects, valid_shape=valid_shape)
    if lens_gain is not None:
        mosaic = mosaic / _sensor.from_planes(lens_gain)
    signal = mosaic
    noise_at = None if not noise else _sensor.ReadoutNoise(
        shot=conditions["noise_shot"], read=conditions["noise_read"], level_knots=profile.noise.level_knots,
        level_variance=conditions.get("noise_level"), correlation_kernel=profile.noise.correlation_kernel,
        correlation_knots=profile.noise.correlation_knots, correlation_weight=profile.noise.correlation_weight)

    # 6-7. Readout: noise at the drawn ISO, banding, early saturation; black and white levels,
    #      quantisation.
    keys = jnp.stack([conditions["noise_key"], conditions["readout_key"]])
    mosaic = _sensor.readout(keys, signal, profile.black_level, profile.white_level, noise=noise_at,
                             effects=profile.effects if effects else None, quantize=quantize, valid_shape=valid_shape)
    outputs = (mosaic,)
    if return_clean:
        clean = jnp.minimum(signal, profile.effects.clip_level) if effects else signal
        outputs += (_sensor.to_digital_numbers(clean, profile.black_level, profile.white_level,
                                               profile.effects if effects else _sensor.no_effects(), quantize=quantize),)
    if return_scene:
        outputs += (scene,)
    return outputs[0] if len(outputs) == 1 else outputs


# colour stages whose mosaic is a matrix on linear sRGB (`conditions["srgb_to_wb_camera"]`)
MATRIX_ON_LINEAR = ("matrix", "spectral")


def _active_content(profile, content: bool | None):
    """The profile's content model when the conversion applies it (`content` True, or None and
    the model's `apply_by_default`), else None; True without a model is an error."""
    model = getattr(profile, "content", None)
    if content and model is None:
        raise ValueError(f"content=True, but profile {profile.info.name!r} has no content model "
                         "(g2r-fit-profile fits one)")
    if model is None or content is False or (content is None and not model.apply_by_default):
        return None
    return model


def _content_pixels(model, linear, grid, draw, count=None):
    """The model on the pixels (a non-linear family); 'scenes' takes its draw, grid and the grid's
    pixels inside a padded image (`count`)."""
    if model.family == "scenes":
        if draw is None:
            raise ValueError("the content model 'scenes' needs the image's draw: conditions from `sample_conditions` "
                             "with this profile")
        return _content.apply(model, linear, draw, None if grid is None else grid(), count)
    return _content.apply(model, linear)


def _content_matrix(model, linear, grid):
    """The model as a 3x3 on linear sRGB (None for a non-linear family); the 'cast' family's
    gains come from `grid()` when given (the image's `content.mean_grid`, decoded on its own)."""
    return _content.as_matrix(model, grid() if grid is not None and model.family == "cast" else linear)


def content_stage(linear, conditions, profile, content: bool | None, colour: str = "matrix", grid=None,
                  highlight_safe: bool = False, grid_count=None):
    """Step 1b: the profile's content model (`g2r_jax.content`) on the scene-linear image, when
    `content` is True, or None and the profile's model says `apply_by_default`; a profile without
    one (every profile before issue 32) is left exactly as it was.

    **Returns:** (linear, conditions). A linear model (`content.as_matrix`) before a colour stage
    that is a matrix on linear sRGB is folded into that matrix (M A: the same result to float
    rounding, no pass over the pixels; the 'cast' family's gains come from `grid()`, when given:
    the image's `content.mean_grid` decoded on its own). The 'scenes' family before such a stage
    (without `highlight_safe`, whose easing is not linear) is split (`content.scenes_split`): its
    gains go into the matrix and its factor per pixel into `conditions["content_tone"]`, which the
    mosaic takes (`render_mosaic`). Otherwise the model transforms the pixels. `grid_count`: the
    grid's pixels inside a zero-padded image (`content.grid_count`)."""
    model = _active_content(profile, content)
    if model is None:
        return linear, conditions
    foldable = colour in MATRIX_ON_LINEAR
    if model.family == "scenes" and foldable and not highlight_safe and conditions.get("content_draw") is not None:
        matrix, tone = _content.scenes_split(model, conditions["content_draw"],
                                             _content.mean_grid(linear) if grid is None else grid(), grid_count)
        return linear, {**conditions, "srgb_to_wb_camera": conditions["srgb_to_wb_camera"] @ matrix,
                        "content_tone": tone}
    matrix = _content_matrix(model, linear, grid)
    if matrix is None or not foldable:
        return _content_pixels(model, linear, grid, conditions.get("content_draw"), grid_count), conditions
    return linear, {**conditions, "srgb_to_wb_camera": conditions["srgb_to_wb_camera"] @ matrix}


def adapted_scene(linear, profile, content: bool | None = None, grid=None, draw=None, grid_count=None):
    """The scene as the camera model sees it: linear sRGB (H, W, 3) after the content model
    that `content_stage` applies (the same model, the same matrix), or `linear` itself when none
    applies. An ISP's consistent target: the mosaic is this scene times the colour stage's
    matrix and the exposure gain (`render_mosaic(..., return_scene=True)`)."""
    model = _active_content(profile, content)
    if model is None:
        return linear
    matrix = _content_matrix(model, linear, grid)
    if matrix is None:
        return _content_pixels(model, linear, grid, draw, grid_count)
    return jnp.einsum("ij,...j->...i", matrix, linear)


def without_content(profile):
    """`profile` without its content model, for conversions of real scenes (the downstream
    controls), which the CG content model (`g2r_jax.content`, applied by default in a fitted
    profile) must not touch."""
    return profile if getattr(profile, "content", None) is None else eqx.tree_at(
        lambda p: p.content, profile, None, is_leaf=lambda x: x is None)


def without_illuminants(profile):
    """`profile` with no illuminant model (None), for conversions that are given their lights
    (`neutral=` of `unprocess` / `unprocess_batch`, e.g. a training set's or a control's fixed
    neutrals): nothing else in the pipeline reads the model, and a program compiled for such a
    profile serves every camera, whatever the size of its illuminant model's arrays."""
    return eqx.tree_at(lambda p: p.illuminants, profile, None, is_leaf=lambda x: x is None)


def _check_image(image, ndim: int = 3):
    if image.ndim != ndim or image.shape[-1] != 3 or image.shape[-3] % 2 or image.shape[-2] % 2:
        expected = "(H, W, 3)" if ndim == 3 else "(B, H, W, 3)"
        raise ValueError(f"image must be {expected} with even H and W, got {image.shape}")


def unprocess(key, image, profile, *, transfer: str = "srgb", neutral=None, iso=None,
              exposure_gain=None, noise: bool = True, effects: bool = True,
              highlight_safe: bool | None = None, recipe: str = "dng", quantize: bool = True, lens_gain=None,
              colour: str = "matrix", return_clean: bool = False, content: bool | None = None,
              return_scene: bool = False):
    """Turn one CG image into a RAW mosaic of the profiled camera.

    **Arguments:**
    - `key`: a `jax.random` key; everything random (illuminant, exposure, ISO, noise) derives from it.
    - `image`: (H, W, 3), H and W even; uint8 codes or float values in [0, 1] (linear for EXR).
    - `profile`: a `SensorProfile`.
    - `transfer`: 'srgb' (exact IEC 61966-2-1 curve), 'gamma2.2' (the published choice) or 'linear'.
    - `neutral`: (3,) camera neutral to use instead of sampling one (G = 1); the profile's
      illuminant model is then not read (it may be None: `without_illuminants`).
    - `iso`, `exposure_gain`: fix these instead of sampling them.
    - `noise`, `effects`: add the profile's noise / non-ideal sensor effects.
    - `highlight_safe`: ease un-white-balance gains to 1 for near-white pixels (Brooks et al.
      2019). Default None: off for recipe 'dng' (a sensor records a grey surface at the
      illuminant's channel ratios up to clipping; see the README, "Highlights"), on for
      'published' (what the published code does).
    - `recipe`: 'dng' (exact DNG colour model) or 'published' (the Graphics2RAW code's
      approximation; see the README).
    - `colour`: 'matrix' (the DNG matrices of the profile), 'spectral' (the profile's spectral
      sensitivities, the neutral as a light spectrum, sRGB upsampled to reflectance by three
      basis spectra: one 3x3 per image) or 'spectral-jakob2019' (Jakob-Hanika upsampling);
      see `g2r_jax.colour.spectral`. Spectral metadata adds `illuminant_family`, `illuminant_spectrum`.
    - `quantize`: return uint16 DN (True) or unrounded float32 DN (False).
    - `lens_gain`: optional (4, H/2, W/2) gain a DNG renderer applies from the camera's
      lens-shading opcodes (`g2r_jax.sensor.shading.shading_gain_planes`); the raw is divided by
      it, so that a renderer applying the opcode gets the scene back.
    - `content`: apply the profile's content model (`g2r_jax.content`) to the scene-linear image
      first: True, False, or None (default) as the profile's model says (`apply_by_default`).
    - `return_clean`: also return the clean mosaic (no noise, no banding; every deterministic
      effect kept), computed in the same pass: a denoiser's (input, target) pair.
    - `return_scene`: also return the scene as the camera saw it (`adapted_scene`): linear sRGB
      (H, W, 3) after the content model, before the exposure gain. With the content model on,
      this, not the input image, is what the mosaic holds: an ISP's consistent target.

    **Returns:** `(mosaic, metadata)`, `(mosaic, clean, metadata)` with `return_clean`,
    `(mosaic, scene, metadata)` with `return_scene`, `(mosaic, clean, scene, metadata)` with both:
    mosaic (H, W) in DN between the black and white levels;
    metadata a dict of arrays: neutral (3,), xy (2,), cct, iso, exposure_gain, noise_shot (4,),
    noise_read (4,) (normalised units per tile position), converged (white-point solve).
    """
    _check_image(image)
    # Steps 2-4: illuminant, white point, colour transform (and the other per-image draws), by the
    # same compiled program as in `unprocess_batch` (so both give the same bytes).
    conditions = jax.tree_util.tree_map(
        lambda x: x[0], batch_conditions(jnp.asarray(key)[None], profile,
                                         neutral=None if neutral is None else jnp.asarray(neutral)[None],
                                         iso=iso, exposure_gain=exposure_gain, recipe=recipe, colour=colour))
    # Steps 1, 5-7: decode, un-white-balance and mosaic, sensor, levels.
    mosaic = render_mosaic(image, conditions, profile, transfer=transfer, noise=noise, effects=effects,
                           highlight_safe=highlight_safe, recipe=recipe, quantize=quantize, lens_gain=lens_gain,
                           colour=colour, return_clean=return_clean, content=content, return_scene=return_scene)
    outputs = mosaic if isinstance(mosaic, tuple) else (mosaic,)
    return (*outputs, _metadata(conditions, colour))


def unprocess_batch(keys, images, profile, *, neutral=None, iso=None, exposure_gain=None,
                    recipe: str = "dng", colour: str = "matrix", valid_shapes=None, **render_options):
    """`unprocess` over a batch (B, H, W, 3) with keys (B, ...), same results image by image
    whatever the batch size or an image's place in it.

    `neutral` (B, 3) fixes every image's light; the profile may then have no illuminant model
    (`without_illuminants(profile)`: one compiled program for every camera's fixed lights).

    The per-image conditions (illuminant, white point, 3x3 matrices) come from
    `batch_conditions` (chunks of a fixed size, so bytes do not depend on how files were batched
    or sharded); the pixels, element-wise, are vmapped. `neutral` is None or (B, 3);
    `iso` and `exposure_gain` are None or shared scalars; `valid_shapes` None or (B, 2) int32
    (h, w) of images zero-padded at the bottom/right to a common shape (each image's top-left
    h x w is then bit for bit its unpadded conversion: how `g2r-convert` batches mixed sizes);
    other options as `unprocess` (with `return_clean=True` the result is
    `(mosaics, clean_mosaics, metadata)`, with `return_scene=True` the adapted scenes follow the
    mosaics as in `unprocess`).
    """
    _check_image(images, ndim=4)
    conditions = batch_conditions(keys, profile, neutral=neutral, iso=iso, exposure_gain=exposure_gain,
                                  recipe=recipe, colour=colour)
    render = lambda image, c, shape: render_mosaic(image, c, profile, recipe=recipe, colour=colour,
                                                   valid_shape=shape, **render_options)
    outputs = jax.vmap(render)(images, conditions, valid_shapes)
    outputs = outputs if isinstance(outputs, tuple) else (outputs,)
    return (*outputs, _metadata(conditions, colour))


CONDITIONS_CHUNK = 32


@eqx.filter_jit
def batch_conditions(keys, profile, *, neutral=None, iso=None, exposure_gain=None, recipe: str = "dng",
                     colour: str = "matrix"):
    """`sample_conditions` for a batch of keys (B, ...), `neutral` None or (B, 3): vmapped over
    chunks of CONDITIONS_CHUNK images (the last one padded with copies of the first key), the
    chunks in a loop (`lax.map`).

    Every image goes through one compiled program of one fixed shape, whatever B and wherever the
    image sits in the batch, so its conditions (and the bytes of its mosaic) do not depend on the
    batch: small matrix products compiled for different batch sizes round differently (on the
    CPU the 3x3 colour transform vmapped over 5 or more images differs in the last bit from the
    same transform for one image). Vmapped, the white-point bisection's loop runs once per chunk:
    as a loop over single images it cost 2.3-3.3 ms per image on an H100 (a device round trip per
    bisection step), 30 times the pixels of a 12-MP frame; on a CPU a chunk costs ~2 ms.
    Jitted, so that a call outside `jax.jit` compiles its loop once per shape, not once per call
    (eager `unprocess`: 3.6 s and about 600 new memory mappings per call before).
    """
    keys = jnp.asarray(keys)
    count = keys.shape[0]
    padded = -(-count // CONDITIONS_CHUNK) * CONDITIONS_CHUNK

    def chunks(x):
        x = jnp.asarray(x)
        if padded > count:
            x = jnp.concatenate([x, jnp.broadcast_to(x[:1], (padded - count,) + x.shape[1:])])
        return x.reshape((padded // CONDITIONS_CHUNK, CONDITIONS_CHUNK) + x.shape[1:])

    def one(args):
        key, row = args
        return sample_conditions(key, profile, neutral=row, iso=iso, exposure_gain=exposure_gain, recipe=recipe,
                                 colour=colour)

    out = jax.lax.map(jax.vmap(one), (chunks(keys), None if neutral is None else chunks(neutral)))
    return jax.tree_util.tree_map(lambda x: x.reshape((padded,) + x.shape[2:])[:count], out)


def image_key(seed: int, index: int):
    """The PRNG key of the `index`-th image of a run with `seed`: order-independent batches."""
    return jax.random.fold_in(jax.random.PRNGKey(seed), index)


def simulate_patches(profile, neutrals, chart_srgb=None, *, recipe: str = "dng", transfer: str = "srgb",
                     seed: int = 0, noise: bool = False, batch: int = 256) -> np.ndarray:
    """Per-channel patch means (N, 24, 3) of the mosaics `unprocess_batch` makes from a chart
    image (sRGB-encoded `chart_srgb`, default `colour.charts.chart_srgb()`; `colour.chart_fit.
    chart_image`) with each image's neutral, exposure gain 1, no sensor effects and no content
    model (a chart's colours are physical, not a renderer's); black level removed, in normalised
    units: the pipeline's side of `colour.chart_fit`'s chart scores."""
    from g2r_jax.colour import charts as _charts
    from g2r_jax.colour.chart_fit import CHART_TILE, chart_image

    chart_srgb = _charts.chart_srgb() if chart_srgb is None else np.asarray(chart_srgb)
    neutrals = np.asarray(neutrals, np.float32)
    image = chart_image(chart_srgb)
    h, w = image.shape[:2]
    black = np.asarray(_sensor.per_position(profile.black_level, (h, w)))
    span = float(profile.white_level) - black
    colours = np.asarray(profile.cfa_pattern)[np.array([[0, 1], [2, 3]])]
    colours = np.tile(colours, (h // 2, w // 2))
    run = jax.jit(lambda keys, images, n: unprocess_batch(
        keys, images, profile, neutral=n, exposure_gain=1.0, noise=noise, effects=False,
        quantize=False, recipe=recipe, transfer=transfer, content=False)[0])
    out = []
    batch = min(batch, len(neutrals))
    for start in range(0, len(neutrals), batch):
        n = neutrals[start:start + batch]
        pad = batch - len(n)
        n_full = np.concatenate([n, np.repeat(n[-1:], pad, 0)]) if pad else n
        keys = jax.vmap(lambda i: image_key(seed, i))(jnp.arange(start, start + batch))
        mosaics = np.asarray(run(keys, jnp.asarray(np.repeat(image[None], batch, 0)), jnp.asarray(n_full)))
        mosaics = ((mosaics - black) / span)[: len(n)]
        tiles = mosaics.reshape(len(n), 4, CHART_TILE, 6, CHART_TILE)
        tile_colours = colours.reshape(4, CHART_TILE, 6, CHART_TILE)
        means = np.stack([np.nanmean(np.where(tile_colours == c, tiles, np.nan), axis=(2, 4)) for c in range(3)], -1)
        out.append(means.reshape(len(n), 24, 3))
    return np.concatenate(out)
