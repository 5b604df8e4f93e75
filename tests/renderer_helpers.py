"""Measuring RAW developers on g2r_jax's DNGs: shared by `benchmarks/renderers_measured.py` and
`tests/test_renderers_measured.py`.

A ColorChecker patch scene (`dng_reference.patch_scene`, enlarged `ENLARGE` times so that each
patch is 64 x 64 pixels and its inner box lies 12 pixels from any demosaicking edge) is converted by
`g2r-convert --no-noise --no-content-model --illuminants CSV` for one camera neutral (the camera's
white for a colour temperature), each developer renders the DNG, each patch's mean inside its box
goes to CIE XYZ (D65) from the developer's output space, and `dng_reference.mean_delta_E_2000`
(one global exposure scale on Y) compares the unclipped patches with the input's XYZ.

Each developer is a function `(dng_path, workdir) -> (H, W, 3) XYZ (D65-adapted) image`, except
the control `model` and the prediction `one_matrix`, which map the DNG's raw patch means straight
to XYZ (`CONTROLS`). The
settings of each are stated next to it (`libraw_options`, `DARKTABLE_CONF`,
`DARKTABLE_ARGUMENTS`, `RAWTHERAPEE_PP3`, `render_adobe_sdk`).
"""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
from pathlib import Path

import colour
import numpy as np

from dng_reference import (D50, D65, mean_delta_E_2000, patch_camera_rgb, patch_scene,
                           render_patches_to_XYZ_D65)

ENLARGE = 4
DEVELOPERS = ("model", "one_matrix", "adobe_sdk", "libraw", "darktable", "darktable_modern", "rawtherapee")
CONTROLS = {"model": "render_model", "one_matrix": "render_one_matrix"}   # per-box, no image
LABELS = {"model": "DNG colour model (colour_hdri), control",
          "one_matrix": "prediction: one ColorMatrix, dcraw's method",
          "adobe_sdk": "Adobe DNG SDK (sdk_render)", "libraw": "LibRaw (rawpy)",
          "darktable": "darktable-cli, legacy white balance", "darktable_modern": "darktable-cli, color calibration",
          "rawtherapee": "rawtherapee-cli"}
SDK_RENDER_ENV = "G2R_SDK_RENDER"


# ---------------------------------------------------------------- scene and conversion

def enlarged_patch_scene(tmp_path: Path):
    """`dng_reference.patch_scene`, each pixel repeated `ENLARGE` times in both directions.

    **Returns:** (folder with patches.png, 8-bit codes (24, 3), boxes (top, left, bottom, right)).
    """
    from PIL import Image

    folder, codes, boxes = patch_scene(tmp_path)
    image = np.asarray(Image.open(folder / "patches.png"))
    Image.fromarray(image.repeat(ENLARGE, 0).repeat(ENLARGE, 1)).save(folder / "patches.png")
    return folder, codes, [tuple(ENLARGE * v for v in box) for box in boxes]


def neutral_for_cct(profile, cct: float) -> np.ndarray:
    """The camera neutral (R/G, 1, B/G) of the Planckian/daylight white of `cct` kelvin under the
    profile's colour matrices (the DNG model's xy -> neutral, in float64)."""
    import jax.numpy as jnp

    from g2r_jax.colour import conversions as gc
    from g2r_jax.colour import dng_model as dng
    from g2r_jax.runtime.x64 import enable_x64

    codes = profile.info.calibration_illuminants
    with enable_x64():
        matrices = np.asarray(profile.colour.color_matrix[:len(codes)], np.float64)
        model = dng.DngColourModel.from_tags(codes, matrices, dtype=np.float64)
        neutral = np.asarray(dng.xy_to_camera_neutral(jnp.asarray(gc.CCT_to_xy(cct)[0]), model))
    return neutral / neutral[1]


def convert_scene(folder: Path, profile_name: str, cct: float, out: Path) -> Path:
    """`g2r-convert` the scene folder for the shipped profile at `cct` K (no noise, no content
    model, one illuminant from a CSV). **Returns:** the DNG's path."""
    from g2r_jax.cli.convert import main as convert_main
    from g2r_jax.profile.schema import load_profile

    profile_path = Path(__file__).resolve().parents[1] / "profiles" / f"{profile_name}.json"
    neutral = neutral_for_cct(load_profile(profile_path), cct)
    out.mkdir(parents=True, exist_ok=True)
    csv = out / "illuminant.csv"
    csv.write_text(f"r_over_g,g,b_over_g\n{neutral[0]:.9f},1,{neutral[2]:.9f}\n")
    status = convert_main([str(folder), "--profile", str(profile_path), "-o", str(out), "--no-noise",
                           "--no-content-model", "--illuminants", str(csv), "--no-progress"])
    if status != 0:
        raise RuntimeError(f"g2r-convert failed ({status}) for {profile_name} at {cct} K")
    return out / "patches.dng"


def input_XYZ(codes: np.ndarray) -> np.ndarray:
    """XYZ (D65) of the input's 8-bit sRGB codes (24, 3)."""
    from g2r_jax.colour import conversions as gc

    return colour.models.eotf_sRGB(codes / 255.0) @ gc.MATRIX_SRGB_TO_XYZ.T


def unclipped_patches(dng_path: Path, codes: np.ndarray, boxes) -> np.ndarray:
    """The patches every developer sees unclipped: below the highlight-safe inflection of the input
    (linear < 0.8: the white patch is out), and below 0.95 of the white level both in the raw and
    after white balance (raw / neutral, scaled so the smallest gain is 1, as LibRaw does)."""
    from g2r_jax.io.dng_read import read_dng_info

    neutral = np.asarray(read_dng_info(dng_path).as_shot_neutral, np.float64)
    camera = patch_camera_rgb(dng_path, boxes)
    balanced = camera * neutral.max() / neutral
    linear = colour.models.eotf_sRGB(codes / 255.0)
    return (linear.max(axis=1) < 0.8) & (camera.max(axis=1) < 0.95) & (balanced.max(axis=1) < 0.95)


# ---------------------------------------------------------------- output spaces

def adapt_D50_to_D65(XYZ: np.ndarray) -> np.ndarray:
    """Bradford D50 -> D65, as `dng_reference.render_patches_to_XYZ_D65` does."""
    return colour.adaptation.chromatic_adaptation_VonKries(XYZ, colour.xy_to_XYZ(D50), colour.xy_to_XYZ(D65),
                                                            transform="Bradford")


def _s15(data: bytes, offset: int, count: int) -> np.ndarray:
    """`count` big-endian s15Fixed16Number values from `offset`."""
    return np.array(struct.unpack(f">{count}i", data[offset:offset + 4 * count]), np.float64) / 65536.0


def _icc_tags(data: bytes) -> dict:
    """{signature: bytes of the tag} of an ICC profile."""
    count = struct.unpack(">I", data[128:132])[0]
    tags = {}
    for index in range(count):
        signature, offset, size = struct.unpack(">4sII", data[132 + 12 * index:144 + 12 * index])
        tags[signature.decode("latin-1")] = data[offset:offset + size]
    return tags


def _icc_curve(tag: bytes):
    """An ICC 'curv' or 'para' tone curve as a function code in [0, 1] -> linear."""
    kind = tag[:4]
    if kind == b"curv":
        n = struct.unpack(">I", tag[8:12])[0]
        if n == 0:
            return lambda x: x
        if n == 1:
            gamma = struct.unpack(">H", tag[12:14])[0] / 256.0
            return lambda x: np.sign(x) * np.abs(x) ** gamma
        table = np.array(struct.unpack(f">{n}H", tag[12:12 + 2 * n]), np.float64) / 65535.0
        return lambda x: np.interp(x, np.linspace(0, 1, n), table)
    if kind == b"para":   # ICC.1:2010 table 68, function types 0-4
        function = struct.unpack(">H", tag[8:10])[0]
        g, a, b, c, d, e, f = (list(_s15(tag, 12, (1, 3, 4, 5, 7)[function])) + [0.0] * 7)[:7]
        if function == 0:
            a, b, c, d, e, f = 1.0, 0.0, 0.0, -np.inf, 0.0, 0.0
        elif function in (1, 2):
            e = c if function == 2 else 0.0
            c, d, f = 0.0, -b / a, e
        elif function == 3:
            e, f = 0.0, 0.0
        return lambda x: np.where(x >= d, np.sign(a * x + b) * np.abs(a * x + b) ** g + e, c * x + f)
    raise ValueError(f"ICC tone curve {kind!r} is not handled")


def icc_to_XYZ_D65(image: np.ndarray, icc: bytes) -> np.ndarray:
    """Pixels in a matrix/TRC ICC profile's space -> XYZ (D65): undo each channel's curve, apply
    the rXYZ/gXYZ/bXYZ columns (PCS, D50) and adapt D50 -> D65 (Bradford)."""
    tags = _icc_tags(icc)
    matrix = np.stack([_s15(tags[f"{c}XYZ"], 8, 3) for c in "rgb"], axis=1)
    linear = np.stack([_icc_curve(tags[f"{c}TRC"])(image[..., i]) for i, c in enumerate("rgb")], -1)
    return adapt_D50_to_D65(linear @ matrix.T)


def read_tiff_with_icc(path: Path):
    """A developer's RGB TIFF as float in [0, 1] (integers divided by their maximum) and its
    embedded ICC profile (bytes). Raises if it has none."""
    import tifffile

    with tifffile.TiffFile(str(path)) as tiff:
        page = tiff.pages[0]
        image = page.asarray()
        icc = page.tags.get("InterColorProfile")
        if icc is None:
            raise ValueError(f"{path}: no embedded ICC profile")
        icc = bytes(icc.value)
    if np.issubdtype(image.dtype, np.integer):
        image = image / float(np.iinfo(image.dtype).max)
    return image[..., :3].astype(np.float64), icc


# ---------------------------------------------------------------- developers

def render_model(dng_path: Path, boxes) -> np.ndarray:
    """The control: each box's mean camera RGB (rawpy's raw values, black-subtracted, normalised)
    through the DNG colour model (colour_hdri; matrices interpolated by the white's temperature).
    **Returns:** XYZ (D65) per box (N, 3)."""
    from g2r_jax.io.dng_read import read_dng_info

    return render_patches_to_XYZ_D65(patch_camera_rgb(dng_path, boxes), read_dng_info(dng_path))


def render_one_matrix(dng_path: Path, boxes) -> np.ndarray:
    """A prediction for a developer that uses one ColorMatrix for every white, as dcraw does
    (`cam_xyz_coeff`): the ColorMatrix of the highest calibration temperature (D65 for most
    cameras, D50 for the GoPro) times sRGB -> XYZ, rows scaled to sum to 1 (camera white -> sRGB
    white), inverted, applied to each box's camera RGB divided by AsShotNeutral (white balance as
    gains on the camera's channels). **Returns:** XYZ (D65) per box."""
    from g2r_jax.colour import conversions as gc
    from g2r_jax.colour.dng_model import calibration_illuminant_cct
    from g2r_jax.io.dng_read import read_dng_info

    info = read_dng_info(dng_path)
    hottest = int(np.argmax([calibration_illuminant_cct(code) for code in info.calibration_illuminants]))
    camera_from_srgb = np.asarray(info.color_matrices[hottest], np.float64) @ gc.MATRIX_SRGB_TO_XYZ
    camera_from_srgb /= camera_from_srgb.sum(axis=1, keepdims=True)
    balanced = patch_camera_rgb(dng_path, boxes) / np.asarray(info.as_shot_neutral, np.float64)
    return balanced @ np.linalg.inv(camera_from_srgb).T @ gc.MATRIX_SRGB_TO_XYZ.T


def sdk_render_program() -> str | None:
    """The `sdk_render` program (benchmarks/dng_sdk_render.cpp built as benchmarks/dng_sdk_padding.py
    says): `$G2R_SDK_RENDER`, else `sdk_render` on the PATH, else None."""
    named = os.environ.get(SDK_RENDER_ENV)
    if named:
        return named if os.access(named, os.X_OK) else None
    return shutil.which("sdk_render")


SDK_SHADOWS = 5.0   # dng_render's default Shadows; black = Shadows * 0.001 of white (dng_render.cpp)


def undo_sdk_encoding(encoded: np.ndarray) -> np.ndarray:
    """Invert what `dng_render` does after the colour matrices at sdk_render's settings: the
    exposure ramp of its default Shadows (`dng_function_exposure_ramp(1, b, b)`, b = 0.005: a black
    point with a quadratic toe of radius b/2) and ProPhoto's gamma 1.8 encode
    (`dng_function_GammaEncode_1_8`: a spline below 8.2e-4, else x^(1/1.8)). Exact away from the
    table's rounding for values above the spline (codes > 0.0193)."""
    ramped = np.clip(encoded, 0.0, None) ** 1.8
    black = SDK_SHADOWS * 0.001
    slope, radius = 1.0 / (1.0 - black), 0.5 * black
    quadratic = slope / (4.0 * radius)
    return np.where(ramped >= radius * slope, black + ramped / slope,
                    black - radius + np.sqrt(ramped / quadratic))


def render_adobe_sdk(dng_path: Path, workdir: Path) -> np.ndarray:
    """Adobe's DNG SDK (`sdk_render`: `dng_render` at its defaults, camera white from AsShotNeutral,
    matrices interpolated by its temperature, final space ProPhoto, float pixels, identity tone
    curve, default crop): `undo_sdk_encoding`, then ProPhoto (D50) -> XYZ D50 -> Bradford D65."""
    out = workdir / "sdk.f32"
    done = subprocess.run([sdk_render_program(), str(dng_path), str(out)], capture_output=True, text=True,
                          check=True, timeout=120)
    width, height, planes = map(int, done.stdout.split())
    image = np.fromfile(out, np.float32).reshape(height, width, planes)[..., :3].astype(np.float64)
    prophoto = colour.RGB_COLOURSPACES["ProPhoto RGB"]
    return adapt_D50_to_D65(undo_sdk_encoding(image) @ prophoto.matrix_RGB_to_XYZ.T)


def libraw_options() -> dict:
    """LibRaw's settings: `g2r_jax.io.reference_render.options()` (camera white balance, no auto
    bright, bright 1, sRGB output, bilinear demosaic, highlights clipped, 16 bits, no flip) with a
    linear curve, gamma (1, 1), in place of the sRGB curve."""
    from g2r_jax.io.reference_render import options

    return {**options(), "gamma": (1.0, 1.0)}


def render_libraw(dng_path: Path, workdir: Path) -> np.ndarray:
    """LibRaw through rawpy at `libraw_options()`: linear sRGB (D65) 16-bit -> XYZ (D65)."""
    import rawpy

    from g2r_jax.colour import conversions as gc

    with rawpy.imread(str(dng_path)) as raw:
        image = raw.postprocess(**libraw_options()).astype(np.float64) / 65535.0
    return image @ gc.MATRIX_SRGB_TO_XYZ.T


DARKTABLE_CONF = ("plugins/darkroom/workflow=none", "plugins/imageio/format/tiff/bpp=32")
DARKTABLE_ARGUMENTS = ("--icc-type", "LIN_REC709")


def render_darktable(dng_path: Path, workdir: Path, adaptation: str = "legacy") -> np.ndarray:
    """darktable-cli, a fresh config folder, no sidecar: workflow none (no filmic, sigmoid, base
    curve or exposure module), `plugins/darkroom/chromatic-adaptation` `legacy` (the white balance
    module at the camera's white, no color calibration) or `modern` (white balance at the camera's
    D65 reference, then color calibration from the as-shot white), the input profile's default
    (the DNG's standard colour matrix), linear Rec.709 output as 32-bit float TIFF; decoded
    through the TIFF's embedded ICC profile. History applied (as the TIFF's XMP lists it):
    rawprepare, demosaic, colorin, colorout, gamma, temperature, highlights, flip
    (+ channelmixerrgb with `modern`)."""
    out = workdir / f"darktable_{adaptation}.tif"
    command = ["darktable-cli", str(dng_path), str(out), *DARKTABLE_ARGUMENTS, "--core",
               "--configdir", str(workdir / "dt_config"), "--cachedir", str(workdir / "dt_cache"),
               "--library", ":memory:"]
    for setting in (*DARKTABLE_CONF, f"plugins/darkroom/chromatic-adaptation={adaptation}"):
        command += ["--conf", setting]
    subprocess.run(command, capture_output=True, text=True, check=True, timeout=300)
    return icc_to_XYZ_D65(*read_tiff_with_icc(out))


def render_darktable_modern(dng_path: Path, workdir: Path) -> np.ndarray:
    """`render_darktable` with modern chromatic adaptation (darktable 4.2's default)."""
    return render_darktable(dng_path, workdir, "modern")


RAWTHERAPEE_PP3 = """[Version]
AppVersion=5.9
Version=349

[White Balance]
Enabled=true
Setting=Camera

[Color Management]
InputProfile=(camera)
ToneCurve=false
ApplyLookTable=false
ApplyBaselineExposureOffset=true
ApplyHueSatMap=false
WorkingProfile=ProPhoto
OutputProfile=RTv4_sRGB
OutputProfileIntent=Relative
"""


def render_rawtherapee(dng_path: Path, workdir: Path) -> np.ndarray:
    """rawtherapee-cli with RawTherapee's neutral processing profile (no `-d`: no auto exposure, no
    curves, no sharpening) plus `RAWTHERAPEE_PP3` (camera white balance, input profile "Camera
    standard" = the matrix RawTherapee takes for the file, no DCP tone curve or look table, sRGB
    output), 32-bit float TIFF, settings and cache in `workdir`; decoded through the TIFF's
    embedded ICC profile. RawTherapee crops 4 pixels on each side ([RAW Bayer] Border=4)."""
    (workdir / "rt").mkdir(exist_ok=True)
    profile, out = workdir / "rt" / "colorimetric.pp3", workdir / "rawtherapee.tif"
    profile.write_text(RAWTHERAPEE_PP3)
    env = {**os.environ, "HOME": str(workdir / "rt"), "RT_SETTINGS": str(workdir / "rt" / "settings"),
           "RT_CACHE": str(workdir / "rt" / "cache"), "XDG_CONFIG_HOME": str(workdir / "rt"),
           "XDG_CACHE_HOME": str(workdir / "rt")}
    subprocess.run(["rawtherapee-cli", "-q", "-o", str(out), "-t", "-b32", "-Y", "-p", str(profile), "-c",
                    str(dng_path)], capture_output=True, text=True, check=True, timeout=300, env=env)
    return icc_to_XYZ_D65(*read_tiff_with_icc(out))


RENDERERS = {"adobe_sdk": render_adobe_sdk, "libraw": render_libraw, "darktable": render_darktable,
             "darktable_modern": render_darktable_modern, "rawtherapee": render_rawtherapee}


def missing(developer: str) -> str | None:
    """Why `developer` cannot run here, or None when it can."""
    import importlib.util

    need = {"model": ["colour_hdri", "rawpy"], "one_matrix": ["colour_hdri", "rawpy"],
            "libraw": ["rawpy"]}.get(developer, [])
    for module in need:
        if importlib.util.find_spec(module) is None:
            return f"python package {module} is not installed"
    if developer == "adobe_sdk" and sdk_render_program() is None:
        return (f"no sdk_render program (set ${SDK_RENDER_ENV} or put it on the PATH; build: "
                "benchmarks/dng_sdk_padding.py)")
    program = {"darktable": "darktable-cli", "darktable_modern": "darktable-cli",
               "rawtherapee": "rawtherapee-cli"}.get(developer)
    if program and shutil.which(program) is None:
        return f"{program} is not on the PATH"
    return None


# ---------------------------------------------------------------- measuring

def box_means(image: np.ndarray, boxes, shape) -> np.ndarray:
    """Mean of `image` inside each box, the boxes given in the DNG's (H, W) `shape`. A developer
    that crops the same number of pixels on opposite sides (RawTherapee: 4) has its boxes moved;
    any other size or orientation is an error."""
    height, width = shape
    dy, dx = height - image.shape[0], width - image.shape[1]
    if dy < 0 or dx < 0 or dy % 2 or dx % 2 or dy > 32 or dx > 32:
        raise ValueError(f"rendered {image.shape[:2]}, expected {shape} or a symmetric crop of it")
    top, left = dy // 2, dx // 2
    return np.array([image[t - top:b - top, l - left:r - left].reshape(-1, 3).mean(axis=0)
                     for t, l, b, r in boxes])


def developer_XYZ(developer: str, dng_path: Path, boxes, workdir: Path) -> np.ndarray:
    """XYZ (D65) per box as `developer` renders the DNG (see `DEVELOPERS`)."""
    if developer in CONTROLS:
        return globals()[CONTROLS[developer]](dng_path, boxes)
    from g2r_jax.io.dng_read import read_dng_info

    info = read_dng_info(dng_path)
    workdir.mkdir(parents=True, exist_ok=True)
    XYZ = box_means(RENDERERS[developer](dng_path, workdir), boxes, (info.height, info.width))
    if np.argmax(XYZ[:, 1]) != 18:   # the white patch (row 4, column 1) must be the brightest
        raise ValueError(f"{developer}: the brightest patch is {np.argmax(XYZ[:, 1])}, not the white one "
                         "(orientation or boxes wrong)")
    return XYZ


def measure(developer: str, dng_path: Path, codes, boxes, workdir: Path) -> dict:
    """Mean CIEDE2000 of `developer`'s rendering against the input over the unclipped patches.

    **Returns:** {"delta_E": float, "max_delta_E": float, "patches": int, "scale": float}.
    """
    keep = unclipped_patches(dng_path, codes, boxes)
    XYZ = developer_XYZ(developer, dng_path, boxes, workdir)[keep]
    reference = input_XYZ(codes)[keep]
    delta_E, scale = mean_delta_E_2000(XYZ, reference)
    lab = colour.XYZ_to_Lab(XYZ * scale, D65), colour.XYZ_to_Lab(reference, D65)
    worst = float(np.max(colour.delta_E(*lab, method="CIE 2000")))
    return {"delta_E": delta_E, "max_delta_E": worst, "patches": int(keep.sum()), "scale": float(scale)}
