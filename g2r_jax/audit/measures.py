"""Per-file statistic vectors, one (n_files, k) array per cause, from `stats.file_statistics`."""

from __future__ import annotations

import numpy as np

DARK_LEVEL = 0.05   # NLF bins below this are read-noise dominated


def noise_prediction(profile, iso: float, level):
    """The profile's noise variance shot(iso) x + read(iso) per position, at `level` (4, B)."""
    isos = np.asarray(profile.noise.iso, np.float64)
    shot = np.array([np.interp(iso, isos, np.asarray(profile.noise.shot, np.float64)[:, p]) for p in range(4)])
    read = np.array([np.interp(iso, isos, np.asarray(profile.noise.read, np.float64)[:, p]) for p in range(4)])
    return shot[:, None] * np.maximum(level, 0) + read[:, None], shot, read


def noise_vector(s, profile) -> np.ndarray:
    """(8,) mean log(measured / predicted variance) over dark and over bright bins, per position."""
    predicted, _, _ = noise_prediction(profile, s["iso"], s["nlf_level"])
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.log(s["nlf_var"] / predicted)
    ratio[~np.isfinite(ratio)] = np.nan
    dark = s["nlf_level"] < DARK_LEVEL
    out = []
    for mask in (dark, ~dark):
        values = np.where(mask & np.isfinite(ratio), ratio, np.nan)
        counts = np.sum(np.isfinite(values), axis=1)
        out.append(np.where(counts > 0, np.nansum(values, axis=1) / np.maximum(counts, 1), np.nan))
    return np.concatenate(out)


_KEYS = {"black_level": "dark_floor", "white_level": "clip", "green_imbalance": "green",
         "lens_shading": "shading", "banding": "band", "exposure_distribution": "brightness",
         "noise_correlation": "noise_corr"}


def vectors(cause: str, file_stats: list, profile) -> np.ndarray:
    """(n_files, k) statistic of `cause` for each file."""
    if cause == "noise_model":
        return np.stack([noise_vector(s, profile) for s in file_stats])
    return np.stack([np.asarray(s[_KEYS[cause]], np.float64) for s in file_stats])


def neutral_chromaticities(file_stats) -> np.ndarray:
    """(n, 2) (r/g, b/g) of the files' as-shot neutrals (files without one are left out)."""
    neutrals = [s["neutral"] for s in file_stats if s.get("neutral") is not None]
    if not neutrals:
        return np.zeros((0, 2))
    n = np.stack(neutrals)
    return np.stack([n[:, 0] / n[:, 1], n[:, 2] / n[:, 1]], 1)
