"""A plain numpy statement of the published per-image steps (the baseline of benchmarks/throughput.py).

What the Graphics2RAW code does for one image, written out in numpy the way it does it: float
arrays, a 2.2 gamma, each 3x3 colour product as a broadcast `(H, W, 1, 3) * (3, 3)` summed over
the last axis and clipped, safe inverted gains (Brooks et al., "Unprocessing Images for Learned
Raw Denoising", CVPR 2019), then a Bayer mosaic and the black/white levels. One image at a time,
in Python. The per-image 3x3 matrices are small and are taken from g2r_jax's 'published' recipe
(row-normalised ColorMatrices interpolated in mired), so both sides do the same colour algebra.

Run as a script it converts a folder of PNGs into DNGs the same way, one after the other
(decode with Pillow, sample an illuminant with numpy, the steps above, our `write_dng_bytes`):

    python benchmarks/published_numpy.py IN_FOLDER OUT_FOLDER [--profile Canon600D] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

GAMMA = 2.2
HIGHLIGHT_INFLECTION = 0.9


def degamma(image_uint8: np.ndarray) -> np.ndarray:
    """8-bit codes -> linear values with a plain 2.2 power law (float32, as the published code)."""
    image = image_uint8.astype(np.float32) / 255.0
    return np.clip(image, 0.0, 1.0) ** GAMMA


def apply_combined_mat(image: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """out[..., i] = clip(sum_j matrix[i, j] * image[..., j], 0, 1), as a broadcast product."""
    out = matrix[np.newaxis, np.newaxis, :, :] * image[:, :, np.newaxis, :]
    return np.clip(np.sum(out, axis=-1), 0.0, 1.0)


def safe_invert_gains(image: np.ndarray, neutral: np.ndarray, rgb_gain: float = 1.0) -> np.ndarray:
    """Un-white-balance (multiply by the neutral), easing the gains to 1 near white."""
    gains = (np.asarray(neutral) * rgb_gain)[np.newaxis, np.newaxis, :]
    gray = np.mean(image, axis=-1, keepdims=True)
    mask = (np.maximum(gray - HIGHLIGHT_INFLECTION, 0.0) / (1.0 - HIGHLIGHT_INFLECTION)) ** 2.0
    safe_gains = np.maximum(mask + (1.0 - mask) * gains, gains)
    return np.clip(image * safe_gains, 0.0, 1.0)


def mosaic(image: np.ndarray, cfa_pattern) -> np.ndarray:
    """(H, W, 3) -> (H, W) Bayer mosaic; cfa_pattern = colour (0 R, 1 G, 2 B) of tile positions."""
    height, width = image.shape[:2]
    bayer = np.empty((height, width), dtype=image.dtype)
    for position, colour in enumerate(cfa_pattern):
        row, col = divmod(position, 2)
        bayer[row::2, col::2] = image[row::2, col::2, colour]
    return bayer


def levels(bayer: np.ndarray, black_level, white_level: float) -> np.ndarray:
    """Normalised mosaic -> uint16 DN between the black level (per tile position) and white."""
    black = np.empty_like(bayer)
    for position, value in enumerate(np.asarray(black_level, np.float64).reshape(4)):
        row, col = divmod(position, 2)
        black[row::2, col::2] = value
    digital = black + bayer * (white_level - black)
    return np.clip(np.round(digital), 0, white_level).astype(np.uint16)


def unprocess_published(image_uint8, srgb_to_xyz, xyz_to_wb_camera, neutral, cfa_pattern, black_level,
                        white_level):
    """The published per-image steps: degamma, sRGB -> XYZ, XYZ -> white-balanced camera RGB
    (both broadcast products), safe inverted gains, mosaic, levels."""
    linear = degamma(image_uint8)
    xyz = apply_combined_mat(linear, srgb_to_xyz)
    camera = apply_combined_mat(xyz, xyz_to_wb_camera)
    camera = safe_invert_gains(camera, np.asarray(neutral) / np.max(neutral))
    return levels(mosaic(camera, cfa_pattern), black_level, white_level)


def published_matrices(profile, neutral):
    """(sRGB -> XYZ, XYZ -> white-balanced camera) of the published recipe for one neutral.

    Same colour model as `g2r_jax.unprocess` with recipe='published' (row-normalised
    ColorMatrices, interpolated in mired at the neutral's CCT, 2500 K for Standard Light A)."""
    import jax.numpy as jnp

    from g2r_jax.colour import conversions as colour, dng_model as dng

    model = profile.colour
    xy, _ = dng.camera_neutral_to_xy(jnp.asarray(neutral, jnp.float32), model, throw=False)
    cct = float(colour.xy_to_CCT(xy))
    low, high = float(model.calibration_cct[0]), float(model.calibration_cct[1])
    low = 2500.0 if low == 2850.0 else low
    weight = 1.0 if low == high else (1.0 / cct - 1.0 / high) / (1.0 / low - 1.0 / high)
    matrices = np.asarray(model.color_matrix, np.float64)
    matrices = matrices / matrices.sum(axis=2, keepdims=True)
    xyz_to_camera = weight * matrices[0] + (1 - weight) * matrices[1]
    return np.asarray(colour.MATRIX_SRGB_TO_XYZ, np.float64), xyz_to_camera


def sample_neutral(rng, profile, attempts: int = 1000):
    """A camera neutral from the profile's illuminant model, drawn the published way: a Gaussian
    draw (first mixture component) rejected until it falls inside the hull."""
    model = profile.illuminants
    mean = np.asarray(model.means[0], np.float64)
    cholesky = np.asarray(model.cholesky[0], np.float64)
    hull = np.asarray(model.hull, np.float64)
    for _ in range(attempts):
        point = mean + cholesky @ rng.standard_normal(2)
        if not model.use_hull or np.all(point @ hull[:, :2].T + hull[:, 2] <= 1e-9):
            break
    else:
        point = mean
    return np.array([point[0], 1.0, point[1]])


def convert_folder(inputs, profile, out_dir, seed: int = 0) -> int:
    """One image after the other: decode, sample, the published steps, write a DNG."""
    from PIL import Image

    from g2r_jax.profile.dng_tags import dng_info_for
    from g2r_jax.io.dng_write import write_dng_bytes

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    cfa = [int(c) for c in np.asarray(profile.cfa_pattern)]
    black, white = np.asarray(profile.black_level, np.float64), float(profile.white_level)
    for path in inputs:
        with Image.open(path) as handle:
            image = np.asarray(handle.convert("RGB"))
        image = image[: image.shape[0] // 2 * 2, : image.shape[1] // 2 * 2]
        neutral = sample_neutral(rng, profile)
        srgb_to_xyz, xyz_to_camera = published_matrices(profile, neutral)
        raw = unprocess_published(image, srgb_to_xyz, xyz_to_camera, neutral, cfa, black, white)
        metadata = {"neutral": neutral, "iso": 100.0, "noise_shot": np.zeros(4), "noise_read": np.zeros(4)}
        info = dng_info_for(profile, metadata, raw.shape[0], raw.shape[1], noise=False)
        (out_dir / f"{Path(path).stem}.dng").write_bytes(write_dng_bytes(raw, info))
    return len(inputs)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("inputs", type=Path, help="folder of PNG/JPEG images")
    parser.add_argument("output", type=Path)
    parser.add_argument("--profile", default="Canon600D")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    from g2r_jax.profile.schema import load_profile

    files = sorted(p for p in args.inputs.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg"))
    count = convert_folder(files, load_profile(args.profile), args.output, args.seed)
    print(f"published_numpy: {count} DNG(s) written to {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
