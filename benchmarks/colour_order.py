"""Issue 8 reproduction: the same colour tag sets in opposite order (A first / D65 first), written with
tifffile, fitted, saved, loaded; CCT of neutral (0.9, 1, 0.35) and the converted mosaics compared.
The DNGs are written by tests/conformance_colour.py next to this script; the g2r_jax imported is
the one on PYTHONPATH, so an older checkout can be measured too:

    PYTHONPATH=. python benchmarks/colour_order.py
"""
from __future__ import annotations

import pathlib
import sys
import tempfile

import jax.numpy as jnp
import numpy as np
import rawpy
from PIL import Image

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent / "tests"))
import conformance_colour as cc  # noqa: E402

from g2r_jax.colour import conversions as gc  # noqa: E402
from g2r_jax.colour import dng_model as dng  # noqa: E402
from g2r_jax.runtime.x64 import enable_x64  # noqa: E402
from g2r_jax.cli.convert import main as convert_main  # noqa: E402
from g2r_jax.examples import colour_checker_srgb  # noqa: E402
from g2r_jax.profile.fitting import fit_profile  # noqa: E402
from g2r_jax.io.dng_read import read_dng_info  # noqa: E402
from g2r_jax.profile.schema import load_profile, save_profile  # noqa: E402

tmp = pathlib.Path(tempfile.mkdtemp())
codes = np.round(colour_checker_srgb() * 255).astype(np.uint8)
img = np.repeat(np.repeat(codes.reshape(4, 6, 3), 16, 0), 16, 1)
(tmp / "in").mkdir(); Image.fromarray(img).save(tmp / "in/p.png")
csv = tmp / "ill.csv"; csv.write_text("r_over_g,g,b_over_g\n0.9,1,0.35\n")
layouts = {"A first (17, 21)": dict(codes=(17, 21), color_matrices=(cc.CM_A, cc.CM_D65), forward_matrices=(cc.FM_A, cc.FM_D65)),
           "D65 first (21, 17)": dict(codes=(21, 17), color_matrices=(cc.CM_D65, cc.CM_A), forward_matrices=(cc.FM_D65, cc.FM_A))}
mosaics = []
for i, (name, layout) in enumerate(layouts.items()):
    info = read_dng_info(cc.write_colour_dng(tmp / f"{i}.dng", **layout))
    save_profile(fit_profile([info], name="cam"), tmp / f"{i}.json")
    with enable_x64():
        xy, _ = dng.camera_neutral_to_xy(jnp.asarray([0.9, 1.0, 0.35]), load_profile(tmp / f"{i}.json", dtype=np.float64).colour)
        print(f"{name}: CCT of neutral (0.9, 1, 0.35) = {float(gc.xy_to_CCT(xy)):.0f} K")
    assert convert_main([str(tmp / "in"), "--profile", str(tmp / f"{i}.json"), "-o", str(tmp / f"o{i}"), "--no-noise",
                         "--illuminants", str(csv), "--no-progress"]) == 0
    with rawpy.imread(str(tmp / f"o{i}/p.dng")) as raw:
        mosaics.append(raw.raw_image.astype(np.int64))
    print(f"  written tags: {read_dng_info(tmp / f'o{i}/p.dng').calibration_illuminants}")
print(f"max |mosaic difference| = {np.abs(mosaics[0] - mosaics[1]).max()} DN")
