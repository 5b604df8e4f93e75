"""What the scenes of the measured and the simulated files hold (issue 32's wiring into the
audit): the content statistics of `g2r_jax.content.scene_statistics` (chroma spread, brightness,
dark and clipped shares, contrast, grey-world cast), per file on a 64 x 64 thumbnail in the camera's
white-balanced RGB (the mosaic's sites averaged per colour, divided by the file's AsShotNeutral,
`content.mosaic_thumbnail`), their medians side by side.

Content is the scene, not the camera: nothing here is tested and nothing is named as a cause.
It tells a user how the scenes the audit compared differ (measured scenes far darker or more
colourful than the built-in dead-leaves scenes), which is worth knowing when reading the
findings and when choosing `--scenes`.
"""

from __future__ import annotations

import numpy as np

from g2r_jax import content
from g2r_jax.profile.fitting import as_shot_neutral

WORDS = {"chroma_spread": "chroma spread (sd of log-chroma)", "brightness": "brightness (mean luminance / peak)",
         "dark_share": "dark share (luminance < 2 % of peak)", "clipped_share": "clipped share",
         "contrast": "contrast (log2 of the 95th / 5th percentile)",
         "cast_red": "grey-world cast, log R/G of the mean", "cast_blue": "grey-world cast, log B/G of the mean"}


def thumbnail(mosaic, info) -> np.ndarray | None:
    """(64, 64, 3) white-balanced camera RGB of one file, or None for a file under 128 x 128 or
    without a usable AsShotNeutral."""
    neutral = as_shot_neutral(info)
    if neutral is None:
        return None
    neutral = np.asarray(neutral, np.float64).reshape(-1)
    if neutral.shape != (3,) or not (np.all(np.isfinite(neutral)) and np.all(neutral > 0)):
        return None
    try:
        rgb = content.mosaic_thumbnail(mosaic, info.cfa_pattern, info.black_level, info.white_level)
    except ValueError:   # smaller than two thumbnails a side
        return None
    return (rgb / neutral).astype(np.float32)


def _medians(files, label: str):
    images = [f["content_thumbnail"] for f in files if f.get("content_thumbnail") is not None]
    if not images:
        return None, 0
    found = content.statistics(np.stack(images), source=f"{label} files")
    out = {}
    for name in content.NAMES:
        values = np.asarray(found.values[name], np.float64)
        values = values[np.isfinite(values)]
        out[name] = float(np.median(values)) if values.size else None
    return out, len(images)


def compare(measured, simulated) -> dict | None:
    """{"names", "measured", "simulated" (medians by name, None where no file has a value),
    "n_measured", "n_simulated"} over the files with a thumbnail, or None when either set has none."""
    m, n_m = _medians(measured, "measured")
    s, n_s = _medians(simulated, "simulated")
    if m is None or s is None:
        return None
    return {"names": list(content.NAMES), "measured": m, "simulated": s, "n_measured": n_m, "n_simulated": n_s,
            "note": "content of the scenes, not a property of the camera: not tested, no verdict"}


def lines(section: dict | None) -> list:
    """Plain lines for the summary (empty without a section)."""
    if not section:
        return []
    fmt = lambda v: "-" if v is None else f"{v:.3g}"
    out = [f"scene content (medians; {section['n_measured']} measured vs {section['n_simulated']} simulated files; "
           f"the scenes, not the camera: not tested)"]
    out += [f"  {WORDS.get(name, name)}: {fmt(section['measured'][name])} vs {fmt(section['simulated'][name])}"
            for name in section["names"]]
    return out
