"""Simulated files: the profile's simulation (`unprocess`) run on scenes, as (mosaic, DngInfo).

One jitted, vmapped call per set; the profile is a jit argument, so changing an effect's
parameters does not recompile. Defect lists are padded to a bucket size with out-of-range
coordinates (dropped by the scatter in `sensor.to_digital_numbers`) so their count does not
change shapes either.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.batch.program_store import stored_program
from g2r_jax.illuminants import distributions as _illuminants
from g2r_jax.profile import schema as _profile
from g2r_jax.io.dng_info import DngInfo
from g2r_jax.pipeline import image_key, unprocess
from g2r_jax.runtime.host_arrays import device_array

_BUCKET = 64


def pad_defects(profile, height: int):
    """The profile with its defect list padded to a multiple of 64 entries (row = 4 * height,
    outside the image, so the padding is dropped)."""
    effects = profile.effects
    count = int(effects.defect_rows.shape[0])
    size = _BUCKET * max(1, -(-count // _BUCKET))
    pad = size - count
    if pad == 0:
        return profile
    padded = type(effects)(
        black_pedestal=effects.black_pedestal, clip_level=effects.clip_level,
        channel_gain=effects.channel_gain, shading=effects.shading,
        defect_rows=jnp.concatenate([effects.defect_rows, jnp.full(pad, 4 * height, jnp.int32)]),
        defect_cols=jnp.concatenate([effects.defect_cols, jnp.zeros(pad, jnp.int32)]),
        defect_values=jnp.concatenate([effects.defect_values, jnp.zeros(pad, effects.defect_values.dtype)]),
        row_noise_std=effects.row_noise_std, column_noise_std=effects.column_noise_std)
    return _profile.replace(profile, effects=padded)


def _simulate_one_batch(keys, images, neutrals, profile, lens_gain):
    return jax.vmap(lambda k, im, n: unprocess(k, im, profile, neutral=n, lens_gain=lens_gain))(keys, images, neutrals)


# traced once per shape and option set, then kept on disk for the next g2r-diagnose (as g2r-convert's)
_simulate_batch = stored_program("audit-simulate", jax.jit(_simulate_one_batch))


def _lens_shading(profile, height: int, width: int):
    """(gain planes or None, OpcodeList2 bytes or None): the profile's lens-shading opcodes at
    this size, as `g2r-convert` writes them (the raw carries the inverse of the gain)."""
    if "OpcodeList2" not in dict(profile.info.opcode_lists):
        return None, None
    from g2r_jax.profile.dng_tags import lens_shading_for

    gain, data = lens_shading_for(profile, height, width)
    return (jnp.asarray(gain), data) if data else (None, None)


def sample_neutrals(keys, illuminants):
    """The neutral `unprocess` would draw for each key (its first sub-key, same sampler)."""
    first = jax.vmap(lambda k: jax.random.split(k, 5)[0])(keys)
    return _illuminants.chromaticity_to_neutral(
        jax.vmap(lambda k: _illuminants.sample_chromaticity(k, illuminants))(first))


def _fixed_illuminants(profile):
    """Stand-in illuminant model of constant shapes (neutrals are passed in explicitly), so that
    illuminant models of any size or kind share one compiled simulation."""
    dtype = profile.illuminants.means.dtype
    return _illuminants.IlluminantModel(weights=jnp.ones(1, dtype), means=jnp.ones((1, 2), dtype),
                                        cholesky=jnp.zeros((1, 2, 2), dtype), hull=jnp.zeros((1, 3), dtype),
                                        kind="gaussian", use_hull=False)


def info_for(profile, metadata: dict, height: int, width: int, index: int = 0) -> DngInfo:
    """The DngInfo a camera with this profile would write for one simulated mosaic."""
    info = profile.info
    colour_tags = profile.colour.dng_tags()
    return DngInfo(
        path=f"<simulated {index}>", width=width, height=height,
        cfa_pattern=tuple(int(c) for c in np.asarray(profile.cfa_pattern)),
        black_level=np.asarray(profile.black_level, np.float64),
        white_level=float(profile.white_level), unique_camera_model=info.unique_camera_model,
        calibration_illuminants=colour_tags["calibration_illuminants"],
        color_matrices=colour_tags["color_matrices"], illuminant_data=colour_tags["illuminant_data"],
        as_shot_neutral=np.asarray(metadata["neutral"], np.float64),
        baseline_exposure=float(profile.baseline_exposure), iso=float(np.round(metadata["iso"])))   # as g2r-convert writes it


def profile_key(profile) -> str:
    """A digest of everything in the profile (its arrays' bytes and its structure): two profiles
    with the same key simulate the same files from the same scenes and seed."""
    import hashlib

    leaves, structure = jax.tree_util.tree_flatten(profile)
    digest = hashlib.sha256(str(structure).encode())
    for leaf in leaves:
        value = np.asarray(leaf)
        digest.update(f"{value.dtype}{value.shape}".encode())
        digest.update(value.tobytes())
    return digest.hexdigest()


def simulate(profile, scenes, seed: int, *, batch: int = 8, keys=None,
             lens_shading: bool | None = None) -> list[tuple[np.ndarray, DngInfo]]:
    """Run the profile's simulation on every scene: the files `g2r-convert` writes.

    **Arguments:** `profile`: a SensorProfile; `scenes`: (N, H, W, 3) sRGB images, uint8 codes
    (as `g2r-convert` reads PNG/JPEG) or floats in [0, 1];
    `seed`: file i uses the key `image_key(seed, i)` (so a set is reproducible, and two profiles
    simulated with the same seed see the same scenes and random draws); `keys`: the N keys
    instead (`convert.file_key(seed, name)` gives `g2r-convert`'s file for that scene and seed);
    `lens_shading`: divide the raw by the profile's lens gain and write its OpcodeList2 (as
    `g2r-convert --lens-shading`); default: when the profile has lens-shading opcodes.

    **Returns:** a list of (uint16 mosaic (H, W), DngInfo).
    """
    scenes = np.asarray(scenes)
    if scenes.dtype != np.uint8:
        scenes = scenes.astype(np.float32)
    n, height, width = scenes.shape[:3]
    padded = _profile.replace(pad_defects(profile, height), illuminants=_fixed_illuminants(profile))
    lens_gain, opcode_list2 = (None, None) if lens_shading is False else _lens_shading(profile, height, width)
    out = []
    for start in range(0, n, batch):
        stop = min(start + batch, n)
        idx = list(range(start, stop)) + [start] * (batch - (stop - start))  # constant batch shape
        keys_now = jnp.stack([image_key(seed, i) if keys is None else keys[i] for i in idx])
        neutrals = sample_neutrals(keys_now, profile.illuminants)
        mosaics, metadata = _simulate_batch(keys_now, device_array(scenes[idx]), neutrals, padded, lens_gain)
        mosaics = np.asarray(mosaics)
        metadata = {k: np.asarray(v) for k, v in metadata.items()}
        for j, i in enumerate(range(start, stop)):
            meta = {k: v[j] for k, v in metadata.items()}
            info = info_for(profile, meta, height, width, i)
            if opcode_list2:
                info.opcode_lists = {"OpcodeList2": opcode_list2}
            out.append((mosaics[j], info))
    return out
