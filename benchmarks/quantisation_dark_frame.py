"""Rounding counted once: dark-frame variance of a sensor against our simulation of it.

    PYTHONPATH=$PWD python benchmarks/quantisation_dark_frame.py [--bits 10] [--size 1024]

A "real" dark frame: analogue read noise of sigma DN on an integer black level, rounded to integer
DN by the ADC (numpy). Its variance is what a NoiseProfile O, a photon-transfer fit or our pixel
fallback reports. Two profiles are fitted from a DNG whose NoiseProfile holds that measurement:
'counted twice' keeps it as the read term (the old behaviour), 'counted once' is what
`fit_profile` does now (read - 1/12 DN^2, `sensor.noise.quantisation`). Each simulates a dark frame
with the simulation's own noise and digitisation steps; the table gives real / simulated variance.
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax import sensor
from g2r_jax.io.dng_info import DngInfo
from g2r_jax.profile import schema
from g2r_jax.profile.fitting import fit_profile

CM_D65 = np.array([[0.6787, -0.1641, -0.0811], [-0.3936, 1.1934, 0.1660], [-0.1016, 0.2686, 0.4541]])


def dark_frame_variance(profile, size: int, seed: int) -> float:
    shot, read = sensor.noise_parameters(100.0, profile.noise)
    noisy = sensor.add_noise(jax.random.PRNGKey(seed), jnp.zeros((size, size), jnp.float32), shot, read)
    return float(np.asarray(sensor.to_digital_numbers(noisy, profile.black_level, profile.white_level,
                                                      profile.effects), np.float64).var())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bits", type=int, default=10)
    parser.add_argument("--size", type=int, default=1024)
    args = parser.parse_args()
    black, white = 64.0, float(2**args.bits - 1)
    span = white - black
    print(f"{args.bits}-bit sensor, black {black:g}, white {white:g}; {args.size}x{args.size} dark frames")
    print(f"{'read sigma (DN)':>16} {'real var':>9} {'sim, twice':>11} {'ratio':>6} {'sim, once':>10} {'ratio':>6}")
    for sigma in (0.3, 0.5, 0.7, 1.0, 2.0):
        real = np.round(black + sigma * np.random.default_rng(1).standard_normal((args.size, args.size)))
        measured = float(real.var())
        info = DngInfo(path="dark.dng", cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, black), white_level=white,
                       unique_camera_model="dark", calibration_illuminants=(21,), color_matrices=(CM_D65,),
                       as_shot_neutral=np.array([0.55, 1.0, 0.6]),
                       noise_profile=np.array([[1e-4, measured / span**2]]), iso=100.0)
        once = fit_profile([info])
        twice = schema.replace(once, noise=sensor.NoiseModel(
            iso=once.noise.iso, shot=once.noise.shot, iso_range=once.noise.iso_range,
            read=jnp.full_like(once.noise.read, measured / span**2)))
        v_twice, v_once = dark_frame_variance(twice, args.size, 3), dark_frame_variance(once, args.size, 3)
        print(f"{sigma:>16.2f} {measured:>9.4f} {v_twice:>11.4f} {measured / v_twice:>6.3f} "
              f"{v_once:>10.4f} {measured / v_once:>6.3f}")


if __name__ == "__main__":
    main()
