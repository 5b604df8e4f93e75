"""Synthetic 10-bit sensors whose dark-frame truth is known, for the read-noise tests (issue 29).

A sensor like the Samsung S20 FE main camera (photon-transfer calibration
../shared/data/noise/s20fe_heteroscedastic_gaussian.csv, var = b1 DN + b2 in DN including black)
with BlackLevel 60, WhiteLevel 1023 and read terms that differ per CFA site. Frames are drawn in
numpy, independently of the simulation under test:

    DN = round(black + DSNU + banding + span * (x (1 + PRNU) + sqrt(shot x + read) n)),
    clipped to [0, white]; hot pixels read a fixed high value in every frame.

The "real dark variance" a fitted profile is judged against is the variance of these integer dark
frames per CFA site, about each frame's own mean (what one dark frame shows); the files have no
NoiseProfile tag. Written as DNGs so that `fit_profile` reads them as it reads a user's folder.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax import sensor
from g2r_jax.audit.synthetic_bursts import scene_signal
from g2r_jax.io.dng_info import DngInfo
from g2r_jax.io.dng_write import write_dng

TABLE = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "noise" / "s20fe_heteroscedastic_gaussian.csv"
TABLE_BLACK = 64.0            # the calibration's black level (PROVENANCE.md)
CM_D65 = np.array([[0.6787, -0.1641, -0.0811], [-0.3936, 1.1934, 0.1660], [-0.1016, 0.2686, 0.4541]])
SITES = ((0, 0), (0, 1), (1, 0), (1, 1))


@dataclasses.dataclass(frozen=True)
class Sensor:
    """Levels in DN; `shot`, `read` (4,) normalised per CFA site, before rounding."""

    iso: float
    shot: tuple
    read: tuple
    black: float = 60.0
    white: float = 1023.0
    dsnu_dn: float = 0.0
    prnu: float = 0.0
    hot_fraction: float = 0.0
    row_banding_dn: float = 0.0

    @property
    def span(self) -> float:
        return self.white - self.black


def s20fe(iso: float, read_scale=(1.0, 1.3, 1.15, 0.85), **extra) -> Sensor:
    """The S20 FE's calibration row at `iso` (read = b1 x 64 + b2 DN^2, its variance at black),
    each site's read variance multiplied by `read_scale`, on a black-60 10-bit range."""
    rows = np.loadtxt(TABLE, delimiter=",", skiprows=1)
    row = rows[rows[:, 0] == iso]
    if len(row) != 4:
        raise ValueError(f"no ISO {iso:g} in {TABLE}")
    row = row[np.argsort(row[:, 1])]
    span = 1023.0 - extra.get("black", 60.0)
    read_dn = (row[:, 2] * TABLE_BLACK + row[:, 3]) * np.asarray(read_scale)
    return Sensor(iso=iso, shot=tuple(row[:, 2] / span), read=tuple(read_dn / span**2), **extra)


def _site_map(values, height, width) -> np.ndarray:
    return np.tile(np.asarray(values, np.float64).reshape(2, 2), (height // 2, width // 2))


def frames(truth: Sensor, signal: np.ndarray, n_frames: int, n_dark: int, seed: int) -> list:
    """[uint16 (H, W) mosaics]: `n_frames` of `signal` (normalised, (H, W)) then `n_dark` dark frames."""
    rng = np.random.default_rng(seed)
    height, width = signal.shape
    shot, read = _site_map(truth.shot, height, width), _site_map(truth.read, height, width)
    gain = 1 + truth.prnu * rng.standard_normal(signal.shape)
    offset = truth.dsnu_dn * rng.standard_normal(signal.shape)
    hot = rng.random(signal.shape) < truth.hot_fraction
    hot_value = rng.uniform(truth.black + 100, truth.white, signal.shape)
    out = []
    for k in range(n_frames + n_dark):
        x = signal * gain if k < n_frames else np.zeros(signal.shape)
        noise = np.sqrt(shot * np.maximum(x, 0) + read) * rng.standard_normal(x.shape)
        banding = truth.row_banding_dn * rng.standard_normal((height, 1))
        dn = truth.black + offset + banding + truth.span * (x + noise)
        dn = np.where(hot, hot_value, dn)
        out.append(np.clip(np.rint(dn), 0, truth.white).astype(np.uint16))
    return out


def info_for(truth: Sensor, path: Path, height: int, width: int) -> DngInfo:
    return DngInfo(path=str(path), width=width, height=height, cfa_pattern=(0, 1, 1, 2),
                   black_level=np.full(4, truth.black), white_level=truth.white,
                   unique_camera_model="G2R S20FE-like 10-bit", calibration_illuminants=(21,),
                   color_matrices=(CM_D65,), as_shot_neutral=np.array([0.55, 1.0, 0.6]), noise_profile=None,
                   iso=truth.iso)


def write_folder(folder: Path, truth: Sensor, *, n_frames=8, n_dark=6, height=256, width=384, seed=0,
                 low=0.002, high=0.3, fine=True) -> tuple[list, list]:
    """Write a burst of a dead-leaves scene and its dark frames as DNGs in `folder`.
    Returns (burst paths, dark-frame paths)."""
    folder.mkdir(parents=True, exist_ok=True)
    signal = scene_signal(seed, height, width, low=low, high=high, fine=fine)
    mosaics = frames(truth, signal, n_frames, n_dark, seed + 1)
    paths = []
    for k, mosaic in enumerate(mosaics):
        path = folder / (f"frame{k:02d}.dng" if k < n_frames else f"dark{k - n_frames:02d}.dng")
        write_dng(path, mosaic, info_for(truth, path, height, width))
        paths.append(path)
    return paths[:n_frames], paths[n_frames:]


def dark_variance(mosaics) -> np.ndarray:
    """(4,) variance per CFA site of dark frames about each frame's own per-site mean, pooled (DN^2)."""
    out = np.zeros(4)
    for p, (dy, dx) in enumerate(SITES):
        planes = [np.asarray(m, np.float64)[dy::2, dx::2] for m in mosaics]
        out[p] = np.mean([plane.var() for plane in planes])
    return out


def simulated_black_variance(profile, iso: float, shape=(512, 768), seed=3) -> np.ndarray:
    """(4,) variance per CFA site of a black frame simulated from `profile` at `iso` by its own noise
    and digitisation steps (as `unprocess` runs them on a black image), DN^2."""
    shot, read = sensor.noise_parameters(jnp.asarray(iso, jnp.float32), profile.noise)
    noisy = sensor.add_noise(jax.random.PRNGKey(seed), jnp.zeros(shape, jnp.float32), shot, read)
    mosaic = np.asarray(sensor.to_digital_numbers(noisy, profile.black_level, profile.white_level, profile.effects))
    return dark_variance([mosaic])
