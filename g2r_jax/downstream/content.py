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
  average surface is from grey (the cue grey-world estimators rely on: Buchsbaum 1980).
The distance between the sets is the difference of medians in units of the real set's robust
standard deviation (1.4826 x MAD, floored), with its sign: positive when the synthetic set's
value is higher.
"""

from __future__ import annotations

import numpy as np

STATISTICS = {
    "brightness": "mean brightness (relative to the brightest pixel)",
    "dark_share": "share of dark pixels (< 2 % of the brightest)",
    "zeroed_share": "share of clipped (zeroed) pixels",
    "contrast": "contrast (log2 of the 95th / 5th percentile)",
    "chroma_spread": "chroma spread of the surfaces (white-balanced log-chroma std)",
    "grey_world_bias": "distance of the mean surface from grey (degrees)",
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
    }
    contrast, spread, bias = np.zeros(n), np.zeros(n), np.zeros(n)
    for i in range(n):
        values = pixels[i][lit[i]]
        if len(values) < 8:
            contrast[i] = spread[i] = bias[i] = np.nan
            continue
        low, high = np.percentile(values.mean(-1), [5, 95])
        contrast[i] = np.log2(high / max(low, _EPS))
        bright = values[values.mean(-1) >= 0.05]
        balanced = np.maximum((bright if len(bright) >= 8 else values) / lights[i], _EPS)
        chroma = np.log(balanced[:, [0, 2]] / balanced[:, 1:2])
        spread[i] = float(np.sqrt(np.mean(np.var(chroma, axis=0))))
        mean = values.mean(0)
        cosine = mean @ lights[i] / (np.linalg.norm(mean) * np.linalg.norm(lights[i]))
        bias[i] = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    out.update(contrast=contrast, chroma_spread=spread, grey_world_bias=bias)
    return out


def _robust_std(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    if len(values) < 2:
        return float("nan")
    return max(1.4826 * float(np.median(np.abs(values - np.median(values)))), 1e-3 * (abs(np.median(values)) + 1e-3))


def compare(synthetic: tuple, real: tuple, control: tuple | None = None) -> list[dict]:
    """How far the synthetic set's content lies from the real set's, per statistic.

    **Arguments:** `synthetic`, `real`: (images, illuminants) each; `control`: optionally the
    real images made RAW again by g2r_jax (their round trip), whose distance is what the
    simulation alone moves a statistic: a CG statistic matters by how far it lies beyond it.
    **Returns:** one dict per statistic, largest excess first: statistic, description, medians
    (synthetic, real, control), distance and control_distance (in the real set's robust standard
    deviations, signed), excess = |distance| - |control_distance|.
    """
    sets = {"synthetic": image_statistics(*synthetic), "real": image_statistics(*real)}
    if control is not None:
        sets["control"] = image_statistics(*control)
    rows = []
    for name, description in STATISTICS.items():
        values = {k: v[name][np.isfinite(v[name])] for k, v in sets.items()}
        if any(not len(v) for v in values.values()):
            continue
        scale = _robust_std(values["real"])
        medians = {k: float(np.median(v)) for k, v in values.items()}
        distance = {k: (medians[k] - medians["real"]) / scale for k in medians}
        row = {"statistic": name, "description": description, **medians, "distance": float(distance["synthetic"])}
        if control is not None:
            row["control_distance"] = float(distance["control"])
        row["excess"] = abs(row["distance"]) - abs(row.get("control_distance", 0.0))
        rows.append(row)
    return sorted(rows, key=lambda r: -r["excess"] if np.isfinite(r["excess"]) else 0.0)
