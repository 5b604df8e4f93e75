"""Does a renderer need pixels outside the DefaultCrop? The Adobe DNG SDK, measured.

    PYTHONPATH=$PWD python benchmarks/dng_sdk_padding.py --sdk-render /path/to/sdk_render

`dng_validate` warns "Too little padding on ... edge of CFA image (possible interpolation
artifacts)" when the DefaultCrop comes within 1.9 pixels of the active area's edge (dng_ifd.cpp);
our DNGs crop nothing. The SDK demosaics with the 2x2 tiles at the border repeated
(dng_mosaic_info.cpp: `edge_repeat` by the CFA repeat size), so the colour phase stays right. This
script renders one scene through the SDK three ways, same 128x96 default crop: (A) no margin, (B) a
2-pixel and (C) an 8-pixel margin of the true scene outside the crop, and (D) the image mirrored
2 pixels outwards (what a converter without scene content beyond the frame could write), and
compares each with (C) in the outer 3 pixels and the interior.

`sdk_render` (benchmarks/dng_sdk_render.cpp) links the libdng of the dngpy wheel; the SDK's
headers are in dngpy's source distribution (`pip download dngpy==0.1.3 --no-binary :all:`):
    S=dngpy-0.1.3; L=$(python -c "import dngpy,os;print(os.path.dirname(dngpy.__file__)+'/../lib')")
    mkdir -p stub/jxl && cp $(find $S/extern/libjxl -name jxl_export.h | head -1) stub/jxl/
    g++ -O1 -std=c++17 -DqDNGValidate=1 -DqDNGValidateTarget=0 -DqDNGUseXMP=1 -DqDNGUseLibJPEG=1 \
        -DqDNGDebug=0 -DqLinux=1 -DUNIX_ENV -DXMP_64=1 -DXMP_StaticBuild=1 -DJXL_STATIC_DEFINE=1 \
        -I$S/extern/dng_sdk/source -I$S/extern/xmp/toolkit/public/include \
        -I$S/extern/libjxl/libjxl/lib/include -Istub benchmarks/dng_sdk_render.cpp -o sdk_render \
        -L$L -l:libdng.so.1 -Wl,-rpath,$L -lpthread
(the jxl headers also need jxl_threads_export.h from the same tree, copied the same way; jxl's own
version.h is on the include path already: `find ... version.h | head -1` would pick brotli's).
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from g2r_jax.io.dng_info import DngInfo
from g2r_jax.io.dng_write import write_dng

H, W = 96, 128
CM_D65 = np.array([[0.6787, -0.1641, -0.0811], [-0.3936, 1.1934, 0.1660], [-0.1016, 0.2686, 0.4541]])


def scene(y, x, kind):
    """Camera RGB in [0, 1] at pixel centres (y, x): flat, a smooth gradient, or texture with sharp steps."""
    if kind == "flat":
        return np.stack([np.full_like(x, 0.3), np.full_like(x, 0.5), np.full_like(x, 0.2)], -1)
    if kind == "smooth":
        return np.stack([0.2 + 0.5 * x / W, 0.3 + 0.4 * y / H, 0.5 - 0.3 * x / W], -1)
    t = 0.5 + 0.35 * np.sin(2 * np.pi * (x + 0.5 * y) / 7.0)
    step = ((x // 9 + y // 11) % 2).astype(float)
    return np.stack([0.1 + 0.6 * t, 0.1 + 0.5 * step, 0.1 + 0.6 * (1 - t)], -1)


def to_mosaic(rgb):
    """RGGB from the top-left pixel (margins are even: the crop keeps the phase)."""
    cfa = np.zeros(rgb.shape[:2], int)
    cfa[0::2, 1::2] = 1
    cfa[1::2, 0::2] = 1
    cfa[1::2, 1::2] = 2
    value = np.take_along_axis(rgb, cfa[..., None], -1)[..., 0]
    return np.round(512 + value * (16383 - 512)).astype(np.uint16)


def render(sdk_render, mosaic, margin, folder, name):
    crop = {} if margin == 0 else {"default_crop_origin": (float(margin),) * 2, "default_crop_size": (float(W), float(H))}
    info = DngInfo(cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, 512.0), white_level=16383.0,
                   unique_camera_model="padding study", calibration_illuminants=(21,), color_matrices=(CM_D65,),
                   as_shot_neutral=np.array([0.5, 1.0, 0.6]), **crop)
    path = folder / f"{name}.dng"
    write_dng(path, mosaic, info)
    out = subprocess.run([sdk_render, str(path), str(path) + ".f32"], capture_output=True, text=True, check=True)
    w, h, c = map(int, out.stdout.split())
    return np.fromfile(str(path) + ".f32", np.float32).reshape(h, w, c)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sdk-render", required=True, help="the sdk_render program (see the docstring)")
    args = parser.parse_args()
    print(f"{'scene':8} {'file':22} {'outer 3 px: mean':>17} {'max':>7} {'interior max':>13}   (|diff| / mean, vs 8-px margin)")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for kind in ("flat", "smooth", "texture"):
            rendered = {}
            for margin in (0, 2, 8):
                y, x = np.mgrid[-margin:H + margin, -margin:W + margin].astype(float)
                rendered[f"{margin}-px true margin"] = render(args.sdk_render, to_mosaic(scene(y, x, kind)), margin,
                                                             folder, f"{kind}{margin}")
            y, x = np.mgrid[0:H, 0:W].astype(float)
            mirrored = np.pad(scene(y, x, kind), ((2, 2), (2, 2), (0, 0)), mode="symmetric")
            rendered["2-px mirrored margin"] = render(args.sdk_render, to_mosaic(mirrored), 2, folder, f"{kind}m")
            reference = rendered.pop("8-px true margin")
            for name, image in rendered.items():
                diff = np.abs(image - reference) / reference.mean()
                edge = np.concatenate([diff[:3].ravel(), diff[-3:].ravel(), diff[:, :3].ravel(), diff[:, -3:].ravel()])
                print(f"{kind:8} {name:22} {edge.mean():>17.4f} {edge.max():>7.4f} {diff[6:-6, 6:-6].max():>13.4f}")


if __name__ == "__main__":
    main()
