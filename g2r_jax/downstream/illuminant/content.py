"""What a CG set's content looks like to the estimator, next to the real files: per-image
statistics of the thumbnails the estimator sees, and how far the synthetic set's distribution
lies from the real one's.

Statistics (each per image; thumbnails are linear camera RGB scaled to a maximum of 1):
- `brightness`: mean luminance (mean of R, G, B) of the thumbnail: how much of the range the
  scene's body fills below its brightest pixel (the exposure and tone of the render);
- `dark_share`: share of pixels below 2 % of the maximum (shadows where noise rules);
- `zeroed_share`: share of pixels zeroed as saturated (or masked) in the thumbnail;
- `contrast`: log2 of the ratio of the 95th to the 5th luminance percentile of lit pixels;
- `chroma_spread`: standard deviation of the white-balanced log-chroma (log r/g, log b/g) of
  pixels above 5 % of the maximum (darker ones are mostly noise), i.e. how colourful the
  scene's surfaces are under a neutral light;
- `grey_world_bias`: angle (degrees) between the image's mean colour and its light: how far its
  average surface is from grey (the cue grey-world estimators rely on: Buchsbaum 1980);
- `bright_share`: share of pixels at or above half the maximum (how much of the frame lies near
  the top of the range: skies, lamps, highlights);
- `light_spread`: standard deviation of log2 luminance over lit pixels (how widely the scene
  spreads its light, in stops);
- `cast_red`, `cast_blue`: the mean surface's colour under a neutral light, log r/g and log b/g
  of the image's mean divided by its light (Buchsbaum's grey world; its spread across the set is
  the spread of the scenes' casts, which a content model that takes every frame to one cast
  removes).
Beside each distance, the spread of the synthetic set's values against the real set's (robust sd
ratio, `spread_ratio`): a set whose median matches can still be far narrower or wider.
The distance between the sets is the difference of medians in units of the real set's robust
standard deviation (`g2r_jax.measure.robust_sd`: 1.4826 x MAD), with its sign: positive when the
synthetic set's value is higher. The spread is floored at the statistic's resolution
(`resolution`), the smallest difference it can show; a real set whose spread is at or below
that floor (every file reads the same share, e.g. no dark pixels anywhere) has no spread to
measure a distance in: the statistic is reported as such (`spread` False, distance NaN), never
as thousands of standard deviations.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.measure import angular_error_degrees, robust_sd

STATISTICS = {
    "brightness": "mean brightness (relative to the brightest pixel)",
    "dark_share": "share of dark pixels (< 2 % of the brightest)",
    "zeroed_share": "share of clipped (zeroed) pixels",
    "contrast": "contrast (log2 of the 95th / 5th percentile)",
    "chroma_spread": "chroma spread of the surfaces (white-balanced log-chroma std)",
    "grey_world_bias": "distance of the mean surface from grey (degrees)",
    "bright_share": "share of bright pixels (>= 50 % of the brightest)",
    "light_spread": "spread of the light (std of log2 luminance, stops)",
    "cast_red": "cast of the mean surface, log r/g under a neutral light",
    "cast_blue": "cast of the mean surface, log b/g under a neutral light",
}
_EPS = 1e-4


def image_statistics(images: np.ndarray, illuminants: np.ndarray) -> dict:
    """Per-image statistics of thumbnails (N, 64, 64, 3) lit by `illuminants` (N, 3): a dict of
    (N,) arrays, keys `STATISTICS`."""
    images = np.asarray(images, np.float64)
    lights = np.asarray(illuminants, np.float64)
    lights = lights / lights[:, 1:2]
    n = len(images)
    pixels = images.reshape(n, -1, 3)
    luminance = pixels.mean(-1)
    zeroed = np.all(pixels <= 0, axis=-1)
    lit = ~zeroed & (luminance > _EPS)
    out = {
        "brightness": luminance.mean(1),
        "dark_share": ((luminance < 0.02) & ~zeroed).mean(1),
        "zeroed_share": zeroed.mean(1),
        "bright_share": ((luminance >= 0.5 * np.maximum(luminance.max(1, keepdims=True), _EPS)) & ~zeroed).mean(1),
    }
    contrast, spread, bias = np.zeros(n), np.zeros(n), np.zeros(n)
    light_spread, cast = np.zeros(n), np.zeros((n, 2))
    for i in range(n):
        values = pixels[i][lit[i]]
        if len(values) < 8:
            contrast[i] = spread[i] = bias[i] = light_spread[i] = np.nan
            cast[i] = np.nan
            continue
        low, high = np.percentile(values.mean(-1), [5, 95])
        contrast[i] = np.log2(high / max(low, _EPS))
        light_spread[i] = float(np.std(np.log2(values.mean(-1))))
        surface = np.maximum(values.mean(0) / lights[i], _EPS)
        cast[i] = np.log(surface[[0, 2]] / surface[1])
        bright = values[values.mean(-1) >= 0.05]
        balanced = np.maximum((bright if len(bright) >= 8 else values) / lights[i], _EPS)
        chroma = np.log(balanced[:, [0, 2]] / balanced[:, 1:2])
        spread[i] = float(np.sqrt(np.mean(np.var(chroma, axis=0))))
        bias[i] = angular_error_degrees(values.mean(0), lights[i], invalid="nan")[0]
    out.update(contrast=contrast, chroma_spread=spread, grey_world_bias=bias, light_spread=light_spread,
               cast_red=cast[:, 0], cast_blue=cast[:, 1])
    return out


def resolution(statistic: str, pixels: int, share: float = 0.0) -> float:
    """The smallest difference `statistic` can show between two images of `pixels` pixels.

    - shares (`dark_share`, `zeroed_share`): the standard error of a binomial proportion,
      sqrt(p (1 - p) / N) at the share p (Cochran, *Sampling Techniques*, 3rd ed. 1977, eq. 3.6),
      and never below 1/N, one pixel's worth;
    - `brightness`, a mean of N values in [0, 1]: one pixel changing across the range, 1/N;
    - `contrast` (log2 of a ratio): 0.01, a ratio of 0.7 %;
    - `chroma_spread` (natural-log chroma): 0.001, 0.1 % in a chroma ratio;
    - `grey_world_bias`: 0.01 degree (estimators err in whole degrees);
    - `light_spread` (stops): 0.01; `cast_red`, `cast_blue` (natural-log ratios): 0.001.
    The last ones are chosen below any difference an estimator can feel.
    """
    n = max(int(pixels), 1)
    if statistic in ("dark_share", "zeroed_share", "bright_share"):
        p = min(max(float(share), 0.0), 1.0)
        return max(float(np.sqrt(p * (1.0 - p) / n)), 1.0 / n)
    return {"brightness": 1.0 / n, "contrast": 0.01, "chroma_spread": 1e-3, "grey_world_bias": 0.01,
            "light_spread": 0.01, "cast_red": 1e-3, "cast_blue": 1e-3}[statistic]


def compare(synthetic: tuple, real: tuple, control: tuple | None = None) -> list[dict]:
    """How far the synthetic set's content lies from the real set's, per statistic.

    **Arguments:** `synthetic`, `real`: (images, illuminants) each; `control`: optionally the
    real images made RAW again by g2r_jax (their round trip), whose distance is what the
    simulation alone moves a statistic: a CG statistic matters by how far it lies beyond it.
    **Returns:** one dict per statistic, largest excess first: statistic, description, medians
    (synthetic, real, control), distance and control_distance (in the real set's robust standard
    deviations, signed), excess = |distance| - |control_distance|; real_spread, synthetic_spread and
    their ratio spread_ratio (the synthetic set's robust sd over the real one's); resolution, and
    `spread` (False when the real files' spread is no larger than the statistic's resolution:
    distance, control_distance and excess are then NaN, and the row sorts last).
    """
    sets = {"synthetic": image_statistics(*synthetic), "real": image_statistics(*real)}
    if control is not None:
        sets["control"] = image_statistics(*control)
    pixels = int(np.prod(np.shape(real[0])[1:3]))
    rows = []
    for name, description in STATISTICS.items():
        values = {k: v[name][np.isfinite(v[name])] for k, v in sets.items()}
        if any(not len(v) for v in values.values()):
            continue
        medians = {k: float(np.median(v)) for k, v in values.items()}
        floor = resolution(name, pixels, max(medians["real"], medians["synthetic"]))
        spread = robust_sd(values["real"], resolution=floor)
        has_spread = bool(np.isfinite(spread) and spread > floor)
        distance = {k: (medians[k] - medians["real"]) / spread if has_spread else float("nan") for k in medians}
        synthetic_spread = robust_sd(values["synthetic"], resolution=floor)
        row = {"statistic": name, "description": description, **medians, "real_spread": float(spread),
               "synthetic_spread": float(synthetic_spread),
               "spread_ratio": float(synthetic_spread / spread) if has_spread else float("nan"),
               "resolution": floor, "spread": has_spread, "distance": float(distance["synthetic"])}
        if control is not None:
            row["control_distance"] = float(distance["control"])
        row["excess"] = (abs(row["distance"]) - abs(row.get("control_distance", 0.0))) if has_spread else float("nan")
        rows.append(row)
    return sorted(rows, key=lambda r: -r["excess"] if np.isfinite(r["excess"]) else np.inf)
