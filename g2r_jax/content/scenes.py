"""The 'scenes' content family (issue 47): each CG frame takes the grey-world cast *and* the
brightness of one of the camera's own scenes, drawn at random per frame, so that the adapted
frames spread over the camera's scenes as its files do, rather than all sharing one mean cast.

The model holds a table of K scenes (`TABLE_SIZE`), each a target colour t_k (linear sRGB,
luminance 1: the scene's grey-world cast, `scene_statistics`, carried from the camera's
white-balanced RGB by the inverse of the profile's sRGB -> white-balanced camera matrix) and a
target brightness b_k (mean luminance over the largest channel value). For a frame with draw
u in [0, 1), k = floor(u K):

1. brightness: the highlights spread upward, the body kept: above the knee C = 1/2 of the frame's
   peak luminance, x1 = x (Y / C)^(q - 1), so Y1 = C (Y / C)^q, each pixel's chroma kept, below it
   x1 = x; q in [1, 8] found by bisection on the frame's mean grid (`model.mean_grid`) so that its
   brightness reaches b_k (it falls as q rises; a frame darker than b_k stays as it is; one the
   curve cannot darken that far takes the least q within `REACH` of the darkest it can be, so a
   flat frame, wholly above its knee, is not raised whole). Real
   scenes owe their low mean under the peak to a few highlights far above a body whose light
   spreads like the CG frames' (docs/pages/validation/content_model.md, finding 4): a power on the
   whole range (Y1 = P (Y / P)^p) reached the brightness too but spread the body's light by p
   (+1.5 to +2.3 robust sd in the check's light spread), and a power on each channel
   (`chroma_tone`) also multiplies every log-chroma by p;
2. cast, as the 'cast' family (`model._gains_toward`): x2_c = x1_c Y_m t_k,c / m_c, m the toned
   frame's mean colour (von Kries gains; Buchsbaum's grey world, J. Franklin Inst. 1980): its
   grey-world cast is then the scene's exactly (q is found with these gains applied, so that the
   brightness is the scene's too).

Both parameters come from the grid; each pixel then takes one scalar factor (a function of its
luminance) and each channel one gain, so a linear colour stage takes the gains into its matrix and
the factor onto its mosaic (`model.scenes_split`, `pipeline.content_stage`): multiplying the
(H, W, 3) image instead kept XLA from fusing the decode with the mosaic (`unprocess` of a
1000 x 1500 frame 3.4 times slower than without the model; docs/pages/validation/content_model.md,
"Cost of applying it"). Fitted from DNGs alone (`fitting.scenes_model`):
the table holds the files' own (cast, brightness) pairs, their casts re-centred on the median
shrunk to the prior's (as 'cast' is), each distinct scene once (`distinct_scenes`: a burst's
frames are one scene). From one scene on it trains the estimators better than 'cast' does from the
same files (`MIN_FILES`: measured with 1, 2, 5, 20 and 50 files, finding 4); without files the
'cast' model of the prior of real scenes remains (a shipped profile). Measurement:
docs/pages/validation/content_model.md, finding 4.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.content.scene_statistics import luminance

TABLE_SIZE = 64
MIN_FILES = 1    # distinct scenes; the measurement found 'scenes' ahead of 'cast' from one file on
# The prior's scenes (`fitting.prior_scene_draws`) the files' table takes as pseudo-files, as the
# lights' kernel takes its prior (`illuminants.kernel.PRIOR_PSEUDO_LIGHTS`): one file's scene then
# fills a sixth of the table, 100 files 95 %. Chosen between 0, 5 and 20 on the inner third of the
# training folds, 1, 5 and 20 files, three NUS cameras, two seeds (content_model.md, finding 5).
PRIOR_SCENES = 5
POWER_RANGE = (1.0, 8.0)
KNEE = 0.5      # of the frame's peak luminance: the threshold of the check's bright share
_BISECTION_STEPS = 20
REACH = 0.01     # of the darkest brightness the curve reaches: an unreachable target's stand-in


SAME_SCENE = (0.02, 0.02, 0.05)   # cells of log r/g, log b/g and log brightness: files in one are one scene


def distinct_scenes(cast_red, cast_blue, brightness) -> np.ndarray:
    """Indices of the files that are distinct scenes, the first of each: files whose casts fall in
    one cell of 0.02 (2 % in a chroma ratio) and whose brightness in one of 5 % are taken as one
    scene (a burst's frames, a file copied), so that a burst of one scene is not a distribution
    of scenes."""
    cells = np.stack([np.floor(np.asarray(v, np.float64) / step) for v, step in
                      zip((cast_red, cast_blue, np.log(brightness)), SAME_SCENE)], -1)
    return np.sort(np.unique(cells, axis=0, return_index=True)[1])


def table_rows(n: int, size: int = TABLE_SIZE) -> np.ndarray:
    """Which of n files fill the table's `size` rows: evenly spaced over the files when there are
    more, each file in turn when fewer (a fixed shape, so one compiled program serves any folder)."""
    if n < 1:
        raise ValueError("no file to fill the scenes table")
    return np.round(np.linspace(0, n - 1, size)).astype(int) if n >= size else np.arange(size) % n


def _luminance(x):
    return luminance(x)[..., 0]


def tone_factor(image, peak, power):
    """(Y / C)^(q - 1) above the knee C = `KNEE` P, 1 below it: the scalar each pixel of images
    (..., H, W, 3) is multiplied by, for peaks P and powers q shaped (..., 1, 1, 1); (..., H, W)."""
    above = jnp.maximum(_luminance(image) / (KNEE * peak[..., 0]), 1.0)
    # one factor per pixel, exp and log rather than a power per channel: a third of the cost
    return jnp.exp((power[..., 0] - 1.0) * jnp.log(above))


def _toned(image, peak, power):
    """x (Y / C)^(q - 1) above the knee, x below it (`tone_factor`)."""
    return image * tone_factor(image, peak, power)[..., None]


def _peak_luminance(grid):
    peak = jnp.max(_luminance(grid), axis=(-2, -1))
    return jnp.where(peak > 0, peak, 1.0)[..., None, None, None]


@jax.jit
def tone_power(grid, brightness, target, count=None):
    """The power q (...,) that takes the brightness of the toned grid (..., h, w, 3), its cast
    then taken to `target` (..., 3) by the 'cast' gains, to `brightness` (...,): by bisection in
    log q over `POWER_RANGE`; a target out of reach is taken as `REACH` above the darkest
    brightness the range can give (the smallest power that comes that near it). With the gains
    g_c = Y_m t_c / m_c the mean luminance is Y_m (t has luminance 1), so the brightness is
    1 / max_c (t_c M_c / m_c), M_c and m_c the toned grid's largest and mean value in channel c:
    no gains applied per step. `count`: how many of the grid's pixels belong to the image when it
    is zero-padded (the means are sums over them; zeros change neither the sums nor the maxima),
    all of them by default. Jitted: outside `jax.jit` its loop compiles once per shape."""
    peak = _peak_luminance(grid)
    low = jnp.full(jnp.shape(brightness), np.log(POWER_RANGE[0]), jnp.float32)
    high = jnp.full(jnp.shape(brightness), np.log(POWER_RANGE[1]), jnp.float32)
    # the log of each grid pixel's luminance over the knee, taken once: each step then takes one exp
    log_above = jnp.log(jnp.maximum(_luminance(grid) / (KNEE * peak[..., 0]), 1.0))
    target = jnp.asarray(target, jnp.float32)
    pixels = (jnp.float32(grid.shape[-3] * grid.shape[-2]) if count is None
              else jnp.asarray(count, jnp.float32)[..., None])

    def reached(log_power):
        toned = grid * jnp.exp((jnp.exp(log_power)[..., None, None] - 1.0) * log_above)[..., None]
        mean = jnp.sum(toned, axis=(-3, -2)) / pixels
        top = jnp.max(toned, axis=(-3, -2))
        ratio = jnp.max(target * top / jnp.where(mean > 0, mean, 1.0), axis=-1)
        return 1.0 / jnp.where(ratio > 0, ratio, 1.0)

    # A frame the curve cannot darken to the scene's brightness takes the least power that comes
    # within `REACH` of the darkest it can make it: a flat frame, all of it at its peak and so above
    # the knee, stays as it is instead of being raised whole by 2^(q - 1).
    brightness = jnp.maximum(brightness, (1.0 + REACH) * reached(high))

    def step(_, bounds):
        low, high = bounds
        middle = 0.5 * (low + high)
        too_bright = reached(middle) > brightness
        return jnp.where(too_bright, middle, low), jnp.where(too_bright, high, middle)

    low, high = jax.lax.fori_loop(0, _BISECTION_STEPS, step, (low, high))
    return jnp.exp(0.5 * (low + high))


def drawn_row(model, draw):
    """The table row of draw u in [0, 1): floor(u K), clipped to the table."""
    size = model.scene_brightness.shape[-1]
    return jnp.clip(jnp.floor(jnp.asarray(draw, jnp.float32) * size).astype(jnp.int32), 0, size - 1)


def scene_parameters(model, draw, grid, cast_gains, count=None):
    """(peak, power, gains) of the 'scenes' transform of images with draws (...,) and their mean
    grids (..., h, w, 3) (`model.mean_grid`): the frame's peak luminance and power q, shaped
    (..., 1, 1, 1), and the cast's gains (..., 1, 1, 3); `cast_gains(grid, target)` gives the
    'cast' family's gains toward targets (..., 3); `count` as `tone_power`'s. The power is found
    with the gains applied, so that the toned frame's brightness is the scene's; the gains on the
    toned grid, so that its grey-world cast is the scene's exactly."""
    row = drawn_row(model, draw)
    target = jnp.asarray(model.scene_casts, jnp.float32)[row]
    brightness = jnp.asarray(model.scene_brightness, jnp.float32)[row]
    power = tone_power(grid, brightness, target, count)[..., None, None, None]
    peak = _peak_luminance(grid)
    return peak, power, cast_gains(_toned(grid, peak, power), target)


def apply_scenes(model, x, draw, grid, cast_gains, count=None):
    """The 'scenes' transform of images x (..., H, W, 3) (`scene_parameters`): the power first,
    then the gains. The transform is a scalar per pixel (`tone_factor`, a function of the pixel's
    luminance) times a diagonal matrix per image, so a linear colour stage may take the gains into
    its matrix and the factor onto its mosaic (`pipeline.content_stage`)."""
    peak, power, gains = scene_parameters(model, draw, grid, cast_gains, count)
    return _toned(x, peak, power) * gains
