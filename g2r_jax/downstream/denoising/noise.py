"""The burst check's noise models (`downstream.denoising.burst_check`, its rows 'upi', 'shipped',
'fitted' and 'truth'): each row's noise at the burst's ISO (`noise_spec` -> `NoiseSpec`), and the
synthetic noisy frames drawn from it inside the denoiser's training step (`synthetic_noisy`,
`model_noise`, `upi_noise`), through the simulation's readout stage (`g2r_jax.sensor.readout`).
"""

from __future__ import annotations

import dataclasses
import warnings

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.downstream.denoising.bursts import Burst, photon_transfer_noise


# ----------------------------------------------------------------------------- noise models

@dataclasses.dataclass(frozen=True)
class NoiseSpec:
    """One row's noise model in normalised units at the burst's ISO: variance = shot * x + read
    per tile position (or `level_variance` (4, K) at `level_knots`), optional `correlation_kernel`
    (4, 3, 3) with its share by level (`correlation_knots`, `correlation_weight`), banding stds;
    `upi`: draw (shot, read) per patch from UPI's prior instead."""

    upi: bool = False
    shot: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(4, np.float32))
    read: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(4, np.float32))
    level_knots: np.ndarray | None = None
    level_variance: np.ndarray | None = None
    correlation_kernel: np.ndarray | None = None
    correlation_knots: np.ndarray | None = None
    correlation_weight: np.ndarray | None = None
    row_noise_std: float = 0.0
    column_noise_std: float = 0.0
    description: str = ""


def _at_iso(noise, iso: float):
    from g2r_jax import sensor

    shot, read = (np.asarray(v, np.float32) for v in sensor.noise_parameters(jnp.float32(iso), noise))
    level = sensor.noise_level_at(jnp.float32(iso), noise)
    return shot, read, None if level is None else np.asarray(level, np.float32)


def _optional(value):
    return None if value is None else np.asarray(value, np.float32)


def _describe(shot, read) -> str:
    return f"shot {np.mean(shot):.3g}, read {np.mean(read):.3g} (mean of 4 positions)"


def noise_spec(row: str, burst: Burst, profile, truth_noise=None) -> NoiseSpec:
    """The `NoiseSpec` of a synthetic row ('upi', 'shipped', 'fitted', 'truth') for `burst`."""
    if row == "upi":
        return NoiseSpec(upi=True, description="drawn per patch: shot log-uniform in [1e-4, 1.2e-2], "
                                               "log read = 2.18 log shot + 1.20 + N(0, 0.26)")
    if row == "shipped":
        noise = profile.noise
        shot, read, level = _at_iso(noise, burst.iso)
        low, high = float(np.min(noise.iso)), float(np.max(noise.iso))
        outside = "" if low * 0.98 <= burst.iso <= high * 1.02 else \
            f"; ISO {burst.iso:g} outside the profile's calibrated {low:g}-{high:g}: held at the nearest row"
        return NoiseSpec(shot=shot, read=read, level_knots=None if level is None else np.asarray(noise.level_knots),
                         level_variance=level, correlation_kernel=_optional(noise.correlation_kernel),
                         correlation_knots=_optional(noise.correlation_knots),
                         correlation_weight=_optional(noise.correlation_weight),
                         row_noise_std=float(profile.effects.row_noise_std),
                         column_noise_std=float(profile.effects.column_noise_std),
                         description=_describe(shot, read) + (", with level function" if level is not None else "")
                         + outside)
    if row == "fitted":
        from g2r_jax.sensor.noise.fallback import noise_and_source

        with warnings.catch_warnings(record=True):
            warnings.simplefilter("always")
            model, source = noise_and_source(list(burst.infos), burst.cfa_pattern)
        shot, read, _ = _at_iso(model, burst.iso)
        return NoiseSpec(shot=shot, read=read, description=f"{_describe(shot, read)}; {source}")
    if row == "truth":
        if truth_noise is None:
            shot, read = photon_transfer_noise(burst)
            where = f"photon transfer over the {burst.n} frames"
        else:
            shot, read = (np.resize(np.asarray(v, np.float64), 4) for v in truth_noise)
            where = "known truth"
        if not (np.all(np.isfinite(shot)) and np.all(np.isfinite(read))):
            raise ValueError(f"photon transfer gave no noise line for this burst (shot {shot}, read {read}): "
                             f"its pixels do not span a range of signals")
        return NoiseSpec(shot=np.asarray(shot, np.float32), read=np.asarray(read, np.float32),
                         description=f"{_describe(shot, read)}; {where}")
    raise ValueError(f"unknown synthetic row {row!r}; expected one of upi, shipped, fitted, truth")


def _noise_arrays(spec: NoiseSpec) -> dict:
    """The arrays of a non-UPI `spec` as a pytree (a jit argument; absent parts None)."""
    as_array = lambda a: None if a is None else jnp.asarray(a, jnp.float32)
    return {"shot": as_array(spec.shot), "read": as_array(spec.read), "level_knots": as_array(spec.level_knots),
            "level_variance": as_array(spec.level_variance), "kernel": as_array(spec.correlation_kernel),
            "correlation_knots": as_array(spec.correlation_knots),
            "correlation_weight": as_array(spec.correlation_weight),
            "banding": jnp.asarray([spec.row_noise_std, spec.column_noise_std], jnp.float32)}


def synthetic_noisy(key, clean, noise: dict, upi: bool, factor, black, span, white):
    """Noisy planes (B, 4, h, w) for clean planes `clean` (normalised): the noise of
    `_noise_arrays` (or UPI's prior per patch when `upi`) with `factor` times its variance,
    rounded to the burst's DN (`black`, `span` (4,), `white`) and clipped to [0, WhiteLevel]
    as a sensor's output is: the simulation's readout stage (`g2r_jax.sensor.readout`), the
    banding drawn per mosaic row and column as in `unprocess`."""
    from g2r_jax import sensor

    batch = clean.shape[0]
    k_levels, k_noise, k_readout = jax.random.split(key, 3)
    if upi:
        from g2r_jax.downstream.base.upi import random_noise_levels

        shot, read = jax.vmap(random_noise_levels)(jax.random.split(k_levels, batch))
        shot, read = jnp.repeat(shot[:, None], 4, 1), jnp.repeat(read[:, None], 4, 1)
        noise = {"level_knots": None, "level_variance": None, "kernel": None, "correlation_knots": None,
                 "correlation_weight": None, "banding": jnp.zeros(2)}
    else:
        shot, read = jnp.broadcast_to(noise["shot"], (batch, 4)), jnp.broadcast_to(noise["read"], (batch, 4))
    level = None if noise["level_variance"] is None else noise["level_variance"] * factor
    banding = noise["banding"] * jnp.sqrt(factor)
    effects = sensor.banding_effects(banding[0], banding[1])

    def one(keys, planes, s, r):
        at_iso = sensor.ReadoutNoise(shot=s * factor, read=r * factor, level_knots=noise["level_knots"],
                                     level_variance=level, correlation_kernel=noise["kernel"],
                                     correlation_knots=noise["correlation_knots"],
                                     correlation_weight=noise["correlation_weight"])
        digital = sensor.readout(keys, sensor.from_planes(planes), black, white, noise=at_iso, effects=effects)
        return sensor.to_planes(digital.astype(jnp.float32))

    keys = jnp.stack([jax.random.split(k_noise, batch), jax.random.split(k_readout, batch)], axis=1)
    digital = jax.vmap(one)(keys, clean, shot, read)
    black, span = black[:, None, None], span[:, None, None]
    return (digital - black) / span


# ----------------------------------------------------------------------------- the rows' noise in training

def model_noise(key, clean, noise_data):
    """`synthetic_noisy` of a profile-like row for the denoiser's step (`denoiser.step_loss_for`):
    `noise_data` = (noise arrays, factor, black, span, white)."""
    noise, factor, black, span, white = noise_data
    return synthetic_noisy(key, clean, noise, False, factor, black, span, white)


def upi_noise(key, clean, noise_data):
    """`synthetic_noisy` with UPI's prior drawn per crop; `noise_data` as `model_noise`'s."""
    noise, factor, black, span, white = noise_data
    return synthetic_noisy(key, clean, noise, True, factor, black, span, white)


def training_noise(spec: NoiseSpec | None, burst: Burst, factor: float):
    """(noise_fn, noise_data) of a row for `denoiser.train_denoiser`; (None, None) for real pairs."""
    if spec is None:
        return None, None
    levels = (jnp.asarray(burst.black, jnp.float32), jnp.asarray(burst.span, jnp.float32), jnp.float32(burst.white))
    if spec.upi:
        return upi_noise, (None, jnp.float32(factor)) + levels
    return model_noise, (_noise_arrays(spec), jnp.float32(factor)) + levels
