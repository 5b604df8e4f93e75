"""The NUS cameras' real thumbnails as small DNGs of each camera, written by our own writer: a
folder a user could have, for the commands that read DNG folders (`g2r-fit-profile`,
`g2r-downstream`).

Each 64 x 64 linear camera-RGB thumbnail of ../shared/data/estimation/nus/<camera>.npz is
mosaicked at the camera profile's CFA, one pixel to one 2x2 tile (128 x 128 DNGs) (`downstream_nus.camera_profile`), scaled to its black
and white levels (pixels saturated in the original, 0 in the npz, written at the white level),
rounded, and written with the profile's colour tags and AsShotNeutral = the measured light
(the grey patches of a ColorChecker in the scene). No noise profile is written: the thumbnails
are means of many pixels.

    python benchmarks/nus_dngs.py Canon600D out/Canon600D_dngs/
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def thumbnail_mosaic(rgb: np.ndarray, cfa_pattern, black_level, white_level: float) -> np.ndarray:
    """(H, W, 3) camera RGB in [0, 1] (0 where saturated) -> (2H, 2W) uint16 CFA mosaic in DN:
    each pixel one 2x2 CFA tile, so a reader's tile thumbnail gives the pixels back."""
    height, width, _ = rgb.shape
    pattern = np.asarray(cfa_pattern).reshape(2, 2)
    levels = np.asarray(black_level, np.float64).reshape(-1)
    black = levels[:4].reshape(2, 2) if levels.size >= 4 else np.full((2, 2), float(levels.min()))
    value = np.where(np.all(rgb <= 0, axis=2, keepdims=True), 1.0, np.clip(rgb, 0.0, 1.0)).astype(np.float64)
    mosaic = np.empty((2 * height, 2 * width))
    for i in range(2):
        for j in range(2):
            mosaic[i::2, j::2] = black[i, j] + value[..., pattern[i, j]] * (white_level - black[i, j])
    return np.round(mosaic).astype(np.uint16)


def write_camera_dngs(camera: str, folder, count: int | None = None) -> list[Path]:
    """Write the first `count` (None: all) thumbnails of NUS `camera` as DNGs into `folder`
    (created); returns their paths."""
    import downstream_nus

    from g2r_jax.downstream.base.real_sets import load_nus
    from g2r_jax.io.dng_write import write_dng
    from g2r_jax.profile.dng_tags import dng_info_for

    real = load_nus(downstream_nus.NUS / f"{camera}.npz")
    profile = downstream_nus.camera_profile(camera)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for k in range(len(real.images) if count is None else min(count, len(real.images))):
        light = real.illuminants[k] / real.illuminants[k][1]
        metadata = {"neutral": light, "noise_shot": np.zeros(4), "noise_read": np.zeros(4), "iso": 100.0}
        mosaic = thumbnail_mosaic(real.images[k], profile.cfa_pattern, profile.black_level, float(profile.white_level))
        info = dng_info_for(profile, metadata, *mosaic.shape, noise=False)
        path = folder / f"{camera}_{k:03d}.dng"
        write_dng(path, mosaic, info)
        written.append(path)
    return written


if __name__ == "__main__":
    paths = write_camera_dngs(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else None)
    print(f"{len(paths)} DNGs of {sys.argv[1]} in {sys.argv[2]}")
