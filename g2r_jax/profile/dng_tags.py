"""A profile's DNG tags for one simulated image: the camera's tags from its profile plus what
was sampled for the image (neutral, ISO, noise), and the lens-shading opcodes rescaled to its size.

Tag meanings: Adobe, *Digital Negative (DNG) Specification* 1.6, ch. 4 (NoiseProfile: variance
S * x + O per colour plane in normalised units) and ch. 7 (OpcodeList2, GainMap). Used by the
batch converter, the audit's and downstream's simulations and the benchmarks alike.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.io.dng_info import DngInfo

__all__ = ["noise_profile_tag", "lens_shading_for", "dng_info_for"]


def noise_profile_tag(shot, read, cfa_pattern) -> np.ndarray:
    """DNG NoiseProfile (S, O) per colour plane R, G, B from per-tile-position parameters."""
    shot, read, cfa = np.asarray(shot, np.float64), np.asarray(read, np.float64), np.asarray(cfa_pattern)
    return np.stack([[shot[cfa == c].mean(), read[cfa == c].mean()] for c in range(3)])


def lens_shading_for(profile, height: int, width: int):
    """(gain planes (4, H/2, W/2), OpcodeList2 bytes rescaled to this size) from the profile's
    lens-shading opcodes; ValueError if the profile has none."""
    from g2r_jax.sensor.shading import rescale_opcode_list, shading_gain_planes

    lists = dict(profile.info.opcode_lists)
    if "OpcodeList2" not in lists:
        raise ValueError(f"profile {profile.info.name!r} has no lens-shading opcodes (OpcodeList2)")
    data = rescale_opcode_list(bytes.fromhex(lists["OpcodeList2"]), None, (height, width), shading_only=True)
    gain = shading_gain_planes({"OpcodeList2": data}, height, width, tuple(np.asarray(profile.cfa_pattern)))
    return gain, data


def dng_info_for(profile, metadata: dict, height: int, width: int, *, noise: bool,
                 opcode_list2: bytes | None = None) -> DngInfo:
    """The DNG tags of one simulated image: the camera's tags plus what was sampled (and the
    lens-shading OpcodeList2 when its inverse was applied)."""
    from g2r_jax.sensor.noise.quantisation import rounding_variance

    colour, info = profile.colour, profile.info
    shot, read = metadata["noise_shot"], metadata["noise_read"]
    has_noise = noise and float(np.max(np.abs(shot))) + float(np.max(np.abs(read))) > 0
    return DngInfo(
        width=width, height=height, cfa_pattern=tuple(int(c) for c in np.asarray(profile.cfa_pattern)),
        black_level=np.asarray(profile.black_level, np.float64), white_level=float(profile.white_level),
        unique_camera_model=info.unique_camera_model, make=info.make or "g2r_jax", model=info.model or info.name,
        **colour.dng_tags(),   # each matrix set with its own illuminant, in the model's order
        analog_balance=np.asarray(colour.analog_balance, np.float64),
        as_shot_neutral=np.asarray(metadata["neutral"], np.float64),
        baseline_exposure=float(profile.baseline_exposure),
        # the noise of the file's integers: the simulation's read term plus its rounding to DN
        noise_profile=noise_profile_tag(shot, np.asarray(read, np.float64) + rounding_variance(
            profile.black_level, float(profile.white_level)), profile.cfa_pattern) if has_noise else None,
        iso=float(np.round(metadata["iso"])),
        opcode_lists={"OpcodeList2": opcode_list2} if opcode_list2 else {})
