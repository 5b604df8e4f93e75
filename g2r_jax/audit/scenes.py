"""Built-in natural-statistics scenes: procedural dead-leaves images, deterministic from a seed.

The dead-leaves model (Matheron 1968; Lee, Mumford & Huang, "Occlusion models for natural
images", IJCV 2001) paints opaque disks front to back with radii drawn from a power law
p(r) ~ r^-3, which gives the scale invariance (1/f^2 power spectrum) of natural images. Each leaf is
flat, so most neighbouring pixels see the same radiance: ideal for noise statistics, while the
occlusion edges and the wide spread of leaf brightness make the images look like scenes to every
statistic that is not about noise. A fraction of leaves are pure black (shadows) and pure white
(speculars, sky), so the dark floor and the clipping level are visible in every file.
"""

from __future__ import annotations

import functools

import numpy as np

BLACK_FRACTION = 0.08
WHITE_FRACTION = 0.06


def _leaf_colour(rng) -> np.ndarray:
    """Display-referred sRGB colour of one leaf: log-uniform lightness, moderate saturation."""
    u = rng.random()
    if u < BLACK_FRACTION:
        return np.zeros(3)
    if u < BLACK_FRACTION + WHITE_FRACTION:
        return np.ones(3)
    lightness = np.exp(rng.uniform(np.log(0.25), np.log(0.95)))
    tint = 1.0 + rng.uniform(-0.35, 0.35, 3)
    return np.clip(lightness * tint / tint.max() * rng.uniform(0.85, 1.0), 0.0, 1.0)


N_LEAVES = 600          # leaves of a 200 x 300 scene (and at least this many at any size)
COVERAGE = 3.0          # leaf area painted per pixel: e^-3 ~ 5 % of the background shows through


def leaf_count(height: int, width: int, r_min: float = 5.0, r_max: float | None = None) -> int:
    """Leaves that paint COVERAGE times the image area on average: area / (pi E[r^2]), with
    E[r^2] = 2 r_min^2 r_max^2 ln(r_max / r_min) / (r_max^2 - r_min^2) for p(r) ~ r^-3 on
    [r_min, r_max]; at least N_LEAVES (the count of 200 x 300 scenes, where this gives ~600).
    A fixed count would leave large scenes mostly background: a 1000 x 1500 scene of 600 leaves
    is ~85 % one colour, with too little black for a dark floor or texture for anything else."""
    r_max = r_max or min(height, width) / 6
    if r_max <= r_min:
        return N_LEAVES
    mean_r2 = 2 * r_min**2 * r_max**2 * np.log(r_max / r_min) / (r_max**2 - r_min**2)
    return int(max(N_LEAVES, round(COVERAGE * height * width / (np.pi * mean_r2))))


def dead_leaves(seed: int, height: int = 200, width: int = 300, *, n_leaves: int | None = None,
                r_min: float = 5.0, r_max: float | None = None) -> np.ndarray:
    """One dead-leaves image (H, W, 3) float32 sRGB in [0, 1].

    **Arguments:** `seed`: the image is a pure function of it; `n_leaves`: leaves painted
    (default `leaf_count`: the same coverage, so the same pixel statistics, at every size);
    `r_min`, `r_max`: leaf radius range in pixels (default maximum: a sixth of the shorter side).

    **Returns:** the image. Leaves are painted back to front over a one-colour background, each
    occluding the earlier ones (the "falling leaves" construction of Lee, Mumford & Huang 2001,
    Sec. 3, truncated to a fixed count); radii by inverse-CDF sampling of p(r) ~ r^-3 on
    [r_min, r_max].
    """
    rng = np.random.default_rng(seed)
    n_leaves = leaf_count(height, width, r_min, r_max) if n_leaves is None else n_leaves
    r_max = r_max or min(height, width) / 6
    image = np.empty((height, width, 3), np.float32)
    image[:] = _leaf_colour(rng)
    u = rng.random(n_leaves)
    radii = 1.0 / np.sqrt(u / r_max**2 + (1 - u) / r_min**2)  # inverse CDF of r^-3
    centres_y = rng.uniform(0, height, n_leaves)
    centres_x = rng.uniform(0, width, n_leaves)
    for radius, cy, cx in zip(radii, centres_y, centres_x):
        top, bottom = max(int(cy - radius), 0), min(int(cy + radius) + 1, height)
        left, right = max(int(cx - radius), 0), min(int(cx + radius) + 1, width)
        yy, xx = np.ogrid[top:bottom, left:right]
        disk = (yy - cy) ** 2 + (xx - cx) ** 2 <= radius**2
        image[top:bottom, left:right][disk] = _leaf_colour(rng)
    return image


def scene_set(n: int, seed: int, height: int = 200, width: int = 300) -> np.ndarray:
    """`n` dead-leaves scenes (n, H, W, 3); scene i depends only on (seed, i). A fresh array each
    call; the last few sets are kept, so a process that audits again (tests, the fuzz harness)
    does not paint the same leaves again (~0.15 s per 200 x 300 scene), and with the compilation
    cache on, sets are kept on disk for the next process (`program_store.stored_array`)."""
    return _scene_set(int(n), int(seed), int(height), int(width)).copy()


@functools.lru_cache(maxsize=4)
def _scene_set(n: int, seed: int, height: int, width: int) -> np.ndarray:
    from g2r_jax.batch.program_store import stored_array

    paint = lambda: np.stack([dead_leaves(int(np.random.SeedSequence([seed, i]).generate_state(1)[0]), height, width)
                              for i in range(n)])
    scenes = stored_array(("dead-leaves scene set", n, seed, height, width), paint)   # kept on disk, as programs
    scenes.setflags(write=False)
    return scenes
