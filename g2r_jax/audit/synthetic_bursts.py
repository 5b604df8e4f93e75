"""Synthetic bursts of one static scene with a known truth: the photon-transfer ground truth the
audit's noise and black-level verdicts are tested against.

Written in numpy, independently of the simulation the audit compares with (`unprocess`), so that
a test against it cannot pass by sharing a mistake with the simulation. Each frame is
DN = round(BlackLevel + pedestal + DSNU + span * (x * PRNU + n)), n ~ N(0, shot x + read) with x
the normalised signal, clipped to [0, WhiteLevel]; PRNU (pixel gain) and DSNU (pixel offset) are
fixed-pattern noise, the same in every frame; dark frames have x = 0. Optional optical-black
columns (`margin`, left of the active area) carry the black without light.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from g2r_jax.io.dng_info import DngInfo
from g2r_jax.audit.scenes import dead_leaves


@dataclasses.dataclass(frozen=True)
class BurstTruth:
    """The camera behind a synthetic burst. Levels in DN; noise in normalised units
    (variance = shot x + read, x = signal / (white - black_tag)); `prnu` relative, `dsnu_dn` DN."""

    black_tag: float = 64.0
    pedestal: float = 0.0
    white: float = 1023.0
    shot: float = 1.0e-5
    read: float = 1.3e-6
    iso: float = 800.0
    prnu: float = 0.0
    dsnu_dn: float = 0.0
    margin: int = 0

    @property
    def span(self) -> float:
        return self.white - self.black_tag


def scene_signal(seed: int, height: int, width: int, *, low: float = 0.004, high: float = 0.06,
                 fine: bool = False) -> np.ndarray:
    """(H, W) normalised signal of a dead-leaves scene (linearised sRGB, one channel per site of
    an RGGB mosaic) mapped to [low, high] of the range: no black unless low = 0. `fine`: a second
    layer of small leaves (radii 1-4 pixels) multiplies the first: texture at the scale of the
    noise estimators' blocks."""
    image = dead_leaves(seed, height, width)
    if fine:
        image = image * (0.6 + 0.4 * dead_leaves(seed + 1, height, width, r_min=1.0, r_max=4.0))
    linear = np.where(image <= 0.04045, image / 12.92, ((image + 0.055) / 1.055) ** 2.4)
    mosaic = np.empty((height, width))
    for dy, dx, c in ((0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 2)):
        mosaic[dy::2, dx::2] = linear[dy::2, dx::2, c]
    return low + (high - low) * mosaic


def burst(truth: BurstTruth, signal: np.ndarray, n_frames: int, seed: int, *, n_dark: int = 0,
          noise_scale: float = 1.0) -> list:
    """[(uint16 mosaic, DngInfo)]: `n_frames` frames of `signal` then `n_dark` dark frames, no
    NoiseProfile tag; `noise_scale` multiplies the true variance (an injected noise error)."""
    rng = np.random.default_rng(seed)
    height, width = signal.shape
    full = width + truth.margin
    gain = 1 + truth.prnu * rng.standard_normal((height, full))
    offset = truth.dsnu_dn * rng.standard_normal((height, full))
    out = []
    for k in range(n_frames + n_dark):
        x = np.zeros((height, full))
        if k < n_frames:
            x[:, truth.margin:] = signal
        x = x * gain
        sd = np.sqrt(noise_scale * (truth.shot * np.maximum(x, 0) + truth.read))
        dn = truth.black_tag + truth.pedestal + offset + truth.span * (x + sd * rng.standard_normal(x.shape))
        raw = np.clip(np.rint(dn), 0, truth.white).astype(np.uint16)
        info = DngInfo(path=f"<{'dark frame' if k >= n_frames else 'frame'} {k}>", width=width, height=height,
                       black_level=np.full(4, truth.black_tag), white_level=truth.white, iso=truth.iso,
                       as_shot_neutral=np.array([0.5, 1.0, 0.6]))
        if truth.margin:
            info.optical_black = raw[:, :truth.margin]
        out.append((raw[:, truth.margin:], info))
    return out


def truth_profile(base, truth: BurstTruth, *, pedestal: float | None = None):
    """`base` with the truth's levels and noise (one ISO row) and black pedestal (`pedestal`
    overrides it: the profile under audit may be wrong about it)."""
    from g2r_jax.profile import schema as _profile

    dtype = base.noise.shot.dtype
    noise = _profile.replace(base.noise, iso=jnp.asarray([truth.iso], dtype), shot=jnp.full((1, 4), truth.shot, dtype),
                             read=jnp.full((1, 4), truth.read, dtype),
                             iso_range=jnp.asarray([truth.iso, truth.iso], dtype))
    effects = _profile.replace(base.effects, black_pedestal=jnp.full(
        4, truth.pedestal if pedestal is None else pedestal, base.effects.black_pedestal.dtype))
    return _profile.replace(base, noise=noise, effects=effects,
                            black_level=jnp.full(4, truth.black_tag, base.black_level.dtype),
                            white_level=jnp.asarray(truth.white, base.white_level.dtype))
