"""Built-in example scenes, so the main command works on a fresh clone.

`colour_checker_scene.png` (480x640, 8-bit sRGB) was made by `make_colour_checker_scene()`:
the 24 ColorChecker patches (CIE L*a*b* of colour-science's 'ColorChecker24 - After November
2014' data, D50, converted to sRGB with Bradford adaptation), a neutral ramp and a hue sweep.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

EXAMPLES_DIR = Path(__file__).resolve().parent
EXAMPLE_SCENE = EXAMPLES_DIR / "colour_checker_scene.png"


def colour_checker_srgb() -> np.ndarray:
    """(24, 3) sRGB-encoded values in [0, 1] of the example's ColorChecker patches
    (`g2r_jax.colour.charts.colour_checker_2014_srgb`)."""
    from g2r_jax.colour.charts import colour_checker_2014_srgb

    return colour_checker_2014_srgb()


def make_colour_checker_scene(height: int = 480, width: int = 640) -> np.ndarray:
    """The example scene as uint8 (height, width, 3)."""
    image = np.zeros((height, width, 3))
    patches = colour_checker_srgb()
    chart_h = int(height * 0.7)
    for index, rgb in enumerate(patches):
        row, col = divmod(index, 6)
        top, left = row * chart_h // 4, col * width // 6
        bottom, right = (row + 1) * chart_h // 4, (col + 1) * width // 6
        image[top:bottom, left:right] = 0.06
        margin = max(2, (right - left) // 10)
        image[top + margin:bottom - margin, left + margin:right - margin] = rgb
    ramp_top = chart_h
    ramp_bottom = chart_h + (height - chart_h) // 2
    image[ramp_top:ramp_bottom] = np.linspace(0, 1, width)[None, :, None]
    hue = np.linspace(0, 1, width, endpoint=False)
    sweep = 0.5 + 0.4 * np.cos(2 * np.pi * (hue[:, None] - np.array([0, 1 / 3, 2 / 3])))
    image[ramp_bottom:] = sweep[None]
    return np.round(image * 255).astype(np.uint8)
