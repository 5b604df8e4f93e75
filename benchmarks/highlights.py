"""Highlights: what `highlight_safe` does to a grey ramp, in the raw and in two renderers (issue 8).

A grey ramp (sRGB codes 0..255) is unprocessed with the Canon 600D profile under a warm and a cool
illuminant, at exposure gains where the ramp's white stays below clipping (0.5), just reaches
it (1.0) and clips (2.0), with `highlight_safe` on and off; each mosaic is written as a DNG and
  - raw: the largest relative deviation of R/G and B/G from the camera neutral over the ramp
    patches that are not clipped (a real sensor records a grey surface at the neutral's ratios);
  - LibRaw (rawpy: camera white balance, sRGB, linear, no auto-brightness, highlight mode clip):
    the largest CIELAB chroma C*ab of a ramp patch, and the 8-bit sRGB of the white patch;
  - colour_hdri (Adobe DNG SDK colour processing, via tests/dng_reference.py): the largest C*ab
    of a ramp patch that is not clipped (it has no highlight handling of its own).

    PYTHONPATH=. python benchmarks/highlights.py
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import colour
import jax
import jax.numpy as jnp
import numpy as np

CODES = np.array([0, 32, 64, 96, 128, 160, 192, 208, 224, 232, 240, 248, 255], np.uint8)
PATCH, MARGIN = 24, 6   # LibRaw opens DNGs of at least 22x22 pixels
ILLUMINANTS = {"warm (2900 K)": 2900.0, "cool (6500 K)": 6500.0}
GAINS = (0.5, 1.0, 2.0)


def ramp_image() -> np.ndarray:
    return np.repeat(np.repeat(CODES[None, :, None], PATCH, 0), PATCH, 1).repeat(3, axis=2)


def boxes():
    return [(MARGIN, i * PATCH + MARGIN, PATCH - MARGIN, (i + 1) * PATCH - MARGIN) for i in range(len(CODES))]


def neutral_for(profile, cct: float) -> np.ndarray:
    from g2r_jax.colour import conversions as gc
    from g2r_jax.colour import dng_model as dng
    from g2r_jax.runtime.x64 import enable_x64

    with enable_x64():
        model = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float64), profile.colour)
        return np.asarray(dng.xy_to_camera_neutral(jnp.asarray(gc.CCT_to_xy(cct)[0]), model))


def write_ramp_dng(path: Path, profile, neutral, gain: float, highlight_safe) -> None:
    from g2r_jax.profile.dng_tags import dng_info_for
    from g2r_jax.io.dng_write import write_dng
    from g2r_jax.pipeline import unprocess

    image = jnp.asarray(ramp_image())
    mosaic, metadata = unprocess(jax.random.PRNGKey(0), image, profile, neutral=jnp.asarray(neutral, jnp.float32),
                                 exposure_gain=gain, noise=False, effects=False, highlight_safe=highlight_safe)
    metadata = {k: np.asarray(v) for k, v in metadata.items()}
    write_dng(path, np.asarray(mosaic), dng_info_for(profile, metadata, *image.shape[:2], noise=False))


def raw_patches(path: Path) -> np.ndarray:
    """Mean (R, G, B) per patch, black-subtracted and normalised to the white level (rawpy)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from dng_reference import patch_camera_rgb

    return patch_camera_rgb(path, boxes())


def chroma_of_linear_srgb(rgb) -> np.ndarray:
    XYZ = colour.RGB_to_XYZ(rgb, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_decoding=False)
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    lab = colour.XYZ_to_Lab(XYZ / max(XYZ[:, 1].max(), 1e-9), white)
    return np.hypot(lab[:, 1], lab[:, 2])


def libraw_render(path: Path):
    """Patch means of LibRaw's linear sRGB render (camera WB, no auto-brightness, highlight clip)."""
    import rawpy

    with rawpy.imread(str(path)) as raw:
        rgb = raw.postprocess(use_camera_wb=True, no_auto_bright=True, gamma=(1, 1), output_bps=16,
                              output_color=rawpy.ColorSpace.sRGB, user_flip=0,
                              highlight_mode=rawpy.HighlightMode.Clip).astype(np.float64) / 65535.0
    means = np.array([rgb[t:b, l:r].reshape(-1, 3).mean(axis=0) for t, l, b, r in boxes()])
    return means


def colour_hdri_chroma(path: Path, camera_rgb) -> np.ndarray:
    from dng_reference import render_patches_to_XYZ_D65

    from g2r_jax.io.dng_read import read_dng_info

    XYZ = render_patches_to_XYZ_D65(camera_rgb, read_dng_info(path))
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    lab = colour.XYZ_to_Lab(XYZ / XYZ[:, 1].max(), white)
    return np.hypot(lab[:, 1], lab[:, 2])


def measure(profile, neutral, gain: float, highlight_safe, folder: Path) -> dict:
    """One row of the table; `highlight_safe` None means unprocess's default."""
    path = folder / f"ramp_{gain}_{highlight_safe}_{neutral[0]:.3f}.dng"
    write_ramp_dng(path, profile, neutral, gain, highlight_safe)
    camera = raw_patches(path)
    unclipped = camera.max(axis=1) < 0.999
    measurable = unclipped & (camera[:, 1] > 0.02)            # above the quantisation of dark patches
    ratios = camera[:, [0, 2]] / np.maximum(camera[:, 1:2], 1e-9)
    deviation = np.abs(ratios / neutral[[0, 2]] - 1)[measurable]
    libraw = libraw_render(path)
    white_8bit = np.round(colour.cctf_encoding(np.clip(libraw[-1] / libraw[-1, 1] * min(libraw[-1, 1], 1), 0, 1)) * 255)
    return {"raw_ratio_error": float(deviation.max()) if deviation.size else float("nan"),
            "clipped_patches": int((~unclipped).sum()),
            "libraw_max_chroma": float(chroma_of_linear_srgb(libraw[1:]).max()),
            "libraw_white_srgb8": tuple(int(v) for v in white_8bit),
            "colour_hdri_max_chroma": float(colour_hdri_chroma(path, camera)[1:][unclipped[1:]].max())}


def main() -> int:
    from g2r_jax.profile.schema import load_profile

    profile = load_profile("Canon600D")
    folder = Path(tempfile.mkdtemp())
    print("| illuminant | exposure gain | highlight_safe | clipped patches | raw R/G, B/G error (unclipped) "
          "| LibRaw max C*ab | LibRaw white (sRGB 8-bit) | colour_hdri max C*ab (unclipped) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, cct in ILLUMINANTS.items():
        neutral = neutral_for(profile, cct)
        for gain in GAINS:
            for safe in (True, False):
                m = measure(profile, neutral, gain, safe, folder)
                print(f"| {name} | {gain} | {safe} | {m['clipped_patches']} | {100 * m['raw_ratio_error']:.2f} % "
                      f"| {m['libraw_max_chroma']:.2f} | {m['libraw_white_srgb8']} | {m['colour_hdri_max_chroma']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
