"""Priors for fitting the content model without a camera's own files.

`REAL_SCENES`: medians of the content statistics of real white-balanced scenes, measured on the
NUS 8-camera colour-constancy set (Cheng, Prasad, Brown, JOSA A 2014; nine cameras, 1,853 raw
thumbnails as republished with the DMCC repository, ../shared/data/PROVENANCE.md), each camera's
thumbnails white-balanced by their measured illuminant (as a DNG's AsShotNeutral would) in the
camera's own RGB; the median of the nine cameras' medians. `REFERENCE_CG`: the same statistics
of the 343 CARLA frames (../shared/data/cg/carla, whole frames decoded from sRGB), taken into each
NUS camera's white-balanced RGB at its median measured light through its Adobe DNG ColorMatrix
pair (../shared/data/cameras/color_matrices.json); the median of the nine. Both are recomputed from the data by
`measure_real_scenes` and `measure_reference_cg` (tests/test_content.py checks the numbers
below against them when the data is present).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

REAL_SCENES = {"medians": {"chroma_spread": 0.22400, "brightness": 0.11634, "cast_red": 0.03337,
                           "cast_blue": -0.06979},
               "source": "prior: NUS 8-camera set, nine cameras (median of per-camera medians)"}
REFERENCE_CG = {"medians": {"chroma_spread": 0.14527, "brightness": 0.31836, "cast_red": -0.08946,
                            "cast_blue": 0.13251},
                "source": "reference CG: 343 CARLA frames"}
# How far one camera's median cast can be trusted from n of its files (`fitting._cast_model`): the
# per-image robust sd of the cast (1.4826 MAD, median over the nine NUS cameras) and the sd of the
# nine cameras' medians about each other, measured on the NUS thumbnails as REAL_SCENES is.
CAST_SPREAD = {"cast_red": {"per_image": 0.1163, "between_cameras": 0.0123},
               "cast_blue": {"per_image": 0.1530, "between_cameras": 0.0254}}
# How the scenes of one camera spread about their medians, for a 'scenes' model without files
# (`fitting.prior_scenes_model`): the covariance of (cast_red, cast_blue, log brightness) over the
# NUS thumbnails, each camera's files centred on its own medians, the nine cameras pooled
# (`scene_covariance`). The casts' sd 0.14 and 0.18, the brightness' a factor of 2.2 (0.78 in log).
SCENE_SPREAD = {"statistics": ("cast_red", "cast_blue", "log brightness"),
                "covariance": ((0.02059, -0.01058, -0.01182), (-0.01058, 0.03085, 0.02360),
                               (-0.01182, 0.02360, 0.60929)),
                "source": "prior: NUS 8-camera set, nine cameras' files about their camera's medians"}
# The fine texture of real scenes, for a profile without files (`content.texture`): the covariance of
# the log texture at 32 pixels across of the NUS thumbnails, the nine cameras' pixels pooled
# (`texture_covariance`); each channel's sd 0.44-0.49, correlated 0.91-0.96.
SCENE_TEXTURE = {"covariance": ((0.21245, 0.19388, 0.20286), (0.19388, 0.19477, 0.20666),
                                (0.20286, 0.20666, 0.24012)),
                 "grid": 32, "source": "prior: NUS 8-camera set, nine cameras' thumbnails pooled"}
NUS_CAMERAS = ("Canon1DsMkIII", "Canon600D", "FujifilmXM1", "NikonD40", "NikonD5200", "OlympusEPL6",
               "PanasonicGX1", "SamsungNX2000", "SonyA57")


def nus_colour_model(matrices_json: Path, camera: str):
    """A NUS camera's DNG colour model from its Adobe ColorMatrix pair (StdA, D65)."""
    import json

    from g2r_jax.colour.dng_model import DngColourModel

    tags = json.loads(Path(matrices_json).read_text())[camera]
    return DngColourModel.from_tags((17, 21), (np.reshape(tags["ColorMatrix_StandardLightA_tag17"], (3, 3)),
                                               np.reshape(tags["ColorMatrix_D65_tag21"], (3, 3))))


def nus_statistics(data: Path, camera: str):
    """`ContentStatistics` of one NUS camera's thumbnails (white-balanced by their measured light)."""
    from g2r_jax.content.real_images import white_balanced_camera_rgb
    from g2r_jax.content.scene_statistics import statistics

    images, lights = _nus(data, camera)
    return statistics(white_balanced_camera_rgb(images, lights), source=f"NUS {camera}")


def _nus(data: Path, camera: str):
    with np.load(Path(data) / "estimation" / "nus" / f"{camera}.npz") as npz:
        return np.asarray(npz["images"]), np.asarray(npz["illuminants"], np.float64)


def measure_real_scenes(data: Path) -> dict:
    """`REAL_SCENES`'s medians recomputed from ../shared/data (`data`)."""
    return real_scenes_without(data, None)


def real_scenes_without(data: Path, camera: str | None) -> dict:
    """`REAL_SCENES`'s medians with the NUS camera `camera` left out (the median of the other eight
    cameras' medians: none of a camera's own scenes informs its own prior); None leaves none out."""
    if camera is not None and camera not in NUS_CAMERAS:
        raise ValueError(f"{camera!r} is not a NUS camera ({', '.join(NUS_CAMERAS)})")
    per_camera = [nus_statistics(data, name).medians() for name in NUS_CAMERAS if name != camera]
    return {k: float(np.median([m[k] for m in per_camera])) for k in per_camera[0]}


def scene_covariance(data: Path, camera: str | None = None) -> np.ndarray:
    """`SCENE_SPREAD`'s covariance (3, 3) recomputed from ../shared/data (`data`), the NUS camera
    `camera` left out when given (none of its own scenes informs its own prior)."""
    if camera is not None and camera not in NUS_CAMERAS:
        raise ValueError(f"{camera!r} is not a NUS camera ({', '.join(NUS_CAMERAS)})")
    centred = []
    for name in NUS_CAMERAS:
        if name == camera:
            continue
        values = nus_statistics(data, name).values
        rows = np.stack([values["cast_red"], values["cast_blue"], np.log(values["brightness"])], -1)
        rows = rows[np.all(np.isfinite(rows), axis=1)]
        centred.append(rows - np.median(rows, axis=0))
    return np.cov(np.concatenate(centred).T)


def measure_reference_cg(data: Path) -> dict:
    """`REFERENCE_CG`'s medians recomputed from the CARLA frames in ../shared/data (`data`)."""
    from PIL import Image

    from g2r_jax.colour.conversions import srgb_decode_lut
    from g2r_jax.content.real_images import srgb_to_white_balanced_camera
    from g2r_jax.content.scene_statistics import SIZE, _area_average, statistics

    table = srgb_decode_lut("srgb")
    frames = np.stack([_area_average(table[np.asarray(Image.open(f).convert("RGB"))][None].astype(np.float64), SIZE)[0]
                       for f in sorted((Path(data) / "cg" / "carla").glob("*.png"))])
    per_camera = []
    for camera in NUS_CAMERAS:
        _, lights = _nus(data, camera)
        colour = nus_colour_model(Path(data) / "cameras" / "color_matrices.json", camera)
        neutral = np.median(lights / lights[:, 1:2], axis=0)
        per_camera.append(statistics(srgb_to_white_balanced_camera(frames, neutral, colour)).medians())
    return {k: float(np.median([m[k] for m in per_camera])) for k in per_camera[0]}


def texture_covariance(data: Path, camera: str | None = None) -> np.ndarray:
    """`SCENE_TEXTURE`'s covariance (3, 3) recomputed from ../shared/data (`data`): the log texture
    (`texture.texture_residuals`) of the NUS thumbnails, the measured pixels of every camera pooled,
    the NUS camera `camera` left out when given."""
    from g2r_jax.content.texture import texture_residuals

    if camera is not None and camera not in NUS_CAMERAS:
        raise ValueError(f"{camera!r} is not a NUS camera ({', '.join(NUS_CAMERAS)})")
    pixels = []
    for name in NUS_CAMERAS:
        if name != camera:
            residuals, kept = texture_residuals(_nus(data, name)[0])
            pixels += [r[k] for r, k in zip(residuals, kept)]
    return np.cov(np.concatenate(pixels).T.astype(np.float64))


def prior_texture(covariance=None, source: str = ""):
    """The `texture.TextureModel` of the prior (`SCENE_TEXTURE`, or `covariance`)."""
    from g2r_jax.content.texture import TextureModel

    covariance = SCENE_TEXTURE["covariance"] if covariance is None else np.asarray(covariance).tolist()
    return TextureModel(covariance=tuple(map(tuple, covariance)), grid=SCENE_TEXTURE["grid"], files=0,
                        source=source or SCENE_TEXTURE["source"])
