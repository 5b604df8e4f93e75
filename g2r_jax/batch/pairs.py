"""What each task trains on, written beside a conversion's DNG (`g2r-convert --pairs`).

The three tasks g2r_jax makes data for each train on a pair:

- denoising: (noisy DNG, clean DNG). The clean DNG is the same conversion without the random
  parts of the sensor (noise, row/column banding), every deterministic effect and the same light,
  exposure, levels and tags kept (no NoiseProfile: it holds no noise); its pixels are the bytes
  `unprocess_batch(..., return_clean=True)` gives.
- illuminant estimation: (DNG, its light in the camera's raw RGB): the manifest's
  `illuminant_rgb`, the DNG's AsShotNeutral normalised to sum 1 as the downstream check labels
  its files (`g2r_jax.downstream.base.real_sets`).
- a neural ISP: (DNG, the display image it should develop to). The *scene target* is the CG frame
  as the camera saw it: after the profile's content model (`pipeline.adapted_scene`), which
  recolours every frame before it is made RAW, so the original render is not what the RAW holds.
  It is written as a 16-bit display-sRGB PNG (IEC 61966-2-1 curve, clipped to [0, 1]) at the
  input's brightness (the manifest's `exposure_gain` is the RAW's scale relative to it), and as
  a linear float EXR where the input was linear. The *developed target* (`--developed`) is what
  the downstream check's reference developer (`g2r_jax.io.reference_render`, LibRaw at the file's
  AsShotNeutral) makes of the clean DNG: the check's "camera look", exposure and LibRaw's one
  colour matrix included.

File names derive from the DNG's (`PAIR_SUFFIXES`): `x.dng`, `x.clean.dng`, `x.scene.png`,
`x.scene.exr`, `x.developed.png`. The neural-ISP task of the downstream check makes its synthetic
pairs with the same functions (`clean_dng_info`, `developed_png`'s developer), so a pair is made
one way.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from g2r_jax.io.dng_info import DngError

__all__ = ["PAIR_SUFFIXES", "pair_outputs", "illuminant_label", "clean_pairs", "clean_dng_info", "scene_png_bytes",
           "scene_exr_bytes", "developed_png_bytes", "output_conflicts"]

PAIR_SUFFIXES = {"clean": ".clean.dng", "scene": ".scene.png", "scene_linear": ".scene.exr",
                 "developed": ".developed.png"}


def pair_outputs(name: str, *, linear: bool, developed: bool) -> dict:
    """The pair's files of the DNG `name.dng`, as paths relative to the output folder.

    **Arguments:** `name`: the DNG's path under the output folder without `.dng`; `linear`: the
    input was decoded as linear light (EXR): a linear scene target is written too; `developed`:
    the reference developer's target is written too.
    **Returns:** {role: path}, roles 'clean', 'scene' and, as asked, 'scene_linear', 'developed'.
    """
    roles = ["clean", "scene"] + (["scene_linear"] if linear else []) + (["developed"] if developed else [])
    return {role: name + PAIR_SUFFIXES[role] for role in roles}


def illuminant_label(neutral) -> list:
    """The illuminant-estimation label of a DNG: its camera neutral (the light in the camera's
    raw RGB) normalised to sum 1, rounded to 8 decimals."""
    neutral = np.asarray(neutral, np.float64)
    return [round(float(v), 8) for v in neutral / neutral.sum()]


def clean_pairs(keys, images, profile, *, neutral=None, transfer: str = "srgb", **options):
    """(mosaics, clean mosaics, scenes, metadata) of a batch: `unprocess_batch(...,
    return_clean=True, return_scene=True)`, the program `g2r-convert --pairs` runs; the ISP task
    calls it with `noise=False` and trains on the clean mosaics. Jit it (or call it inside a jitted
    step); other options as `unprocess_batch`."""
    from g2r_jax.pipeline import unprocess_batch

    return unprocess_batch(keys, images, profile, neutral=neutral, transfer=transfer, return_clean=True,
                           return_scene=True, **options)


def clean_dng_info(profile, metadata: dict, height: int, width: int, *, opcode_list2: bytes | None = None):
    """The tags of a clean DNG: those of the conversion's DNG (`profile.dng_tags.dng_info_for`,
    the same AsShotNeutral, levels, matrices, baseline exposure, ISO, opcodes) without a
    NoiseProfile."""
    from g2r_jax.profile.dng_tags import dng_info_for

    return dng_info_for(profile, metadata, height, width, noise=False, opcode_list2=opcode_list2)


def _png16(codes: np.ndarray) -> bytes:
    import imagecodecs

    return imagecodecs.png_encode(np.ascontiguousarray(codes, np.uint16))


def srgb_codes(linear) -> np.ndarray:
    """Linear sRGB (H, W, 3) -> 16-bit display-sRGB codes (the IEC 61966-2-1 curve, clipped to [0, 1])."""
    from g2r_jax.colour.conversions import linear_to_srgb

    encoded = np.asarray(linear_to_srgb(np.clip(np.asarray(linear, np.float64), 0.0, 1.0)), np.float64)
    return np.round(np.clip(encoded, 0.0, 1.0) * 65535.0).astype(np.uint16)


def scene_png_bytes(scene_linear) -> bytes:
    """The scene target as a 16-bit sRGB PNG: `scene_linear` (H, W, 3) linear sRGB, encoded by
    `srgb_codes`."""
    return _png16(srgb_codes(scene_linear))


def scene_exr_bytes(scene_linear) -> bytes:
    """The scene target as a linear-light float32 OpenEXR (channels R, G, B, no clipping)."""
    import OpenEXR

    scene = np.ascontiguousarray(np.asarray(scene_linear, np.float32))
    channels = {c: np.ascontiguousarray(scene[..., i]) for i, c in enumerate("RGB")}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with tempfile.TemporaryDirectory(prefix="g2r-exr-") as folder:
        path = os.path.join(folder, "scene.exr")
        with OpenEXR.File(header, channels) as exr:
            exr.write(path)
        return Path(path).read_bytes()


def developed_png_bytes(dng_bytes: bytes, name: str) -> bytes:
    """The reference developer's image of a DNG (`g2r_jax.io.reference_render.develop`: LibRaw at
    its AsShotNeutral, sRGB, no auto-brightening) as a 16-bit PNG. **Raises:** `DngError` naming
    `name` when LibRaw cannot develop it."""
    from g2r_jax.io.reference_render import develop

    return _png16(np.round(develop(dng_bytes, name=name) * 65535.0))


def output_conflicts(inputs, names, out_dir, roles_of) -> dict:
    """Inputs whose outputs would collide, found before anything is written.

    **Arguments:** `inputs` paths; `names` each input's DNG path under `out_dir` without `.dng`;
    `out_dir`; `roles_of(index)` -> {role: relative path} of every file input `index` writes
    (its DNG included). **Returns:** {input index: the problem}, for each input one of whose
    files would also be written for another input, or would overwrite an input file.
    """
    claims = {}
    for index in range(len(inputs)):
        for role, relative in roles_of(index).items():
            claims.setdefault(os.path.normcase(os.path.abspath(Path(out_dir) / relative)), []).append((index, relative))
    sources = {os.path.normcase(os.path.abspath(p)): Path(p) for p in inputs}
    problems = {}
    for path, owners in claims.items():
        if path in sources:
            for index, relative in owners:
                problems.setdefault(index, f"its output {relative} would overwrite the input {sources[path]}; "
                                           "write into another folder (-o)")
        if len(owners) > 1:
            for index, relative in owners:
                others = sorted({str(inputs[i]) for i, _ in owners if i != index})
                problems.setdefault(index, f"its output {relative} would also be written for {', '.join(others)}; "
                                           "rename one")
    return problems


def pair_record(pair: dict) -> dict:
    """The manifest's `pair` entry: {role: relative path} with POSIX separators."""
    return {role: Path(path).as_posix() for role, path in pair.items()}


def checked_size(name: str, scene: np.ndarray, mosaic_shape) -> None:
    """A scene target must have the mosaic's geometry (a bug otherwise, named by file)."""
    if tuple(scene.shape[:2]) != tuple(mosaic_shape):
        raise DngError(name, f"scene target {scene.shape[:2]} does not match the mosaic {tuple(mosaic_shape)}")
