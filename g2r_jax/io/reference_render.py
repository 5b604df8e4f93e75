"""The reference renderer: one fixed RAW developer that makes the display-sRGB image of every DNG,
real or synthetic, the same way: the neural-ISP task's targets (`g2r_jax.downstream.isp.pairs`)
and the "camera look" target of `g2r-convert --pairs --developed` (`g2r_jax.batch.pairs`).

The paper (Graphics2RAW, Seo et al. ICCV 2023, supplement S1.3) rendered both its real and its
synthetic DNGs with Adobe Camera Raw at the same settings and each file's as-shot white balance;
a network then learns RAW -> that sRGB. We use LibRaw (through `rawpy`, already a dependency) for
the same role: a well-kept developer independent of g2r_jax, so that none of g2r_jax's own colour
code makes a target (a target rendered by our DNG colour model would reward synthetic RAW for
agreeing with that model rather than with a camera's files).

Options (`OPTIONS`, fixed, identical for every file):
- white balance: the file's own AsShotNeutral (`use_camera_wb=True`, never LibRaw's auto white
  balance), so the network must learn the white balance from the pixels;
- brightness: no histogram-based brightening (`no_auto_bright=True`) and a fixed `bright=1.0`,
  so that the white level maps to white and the target is a function of the file alone;
- colour: LibRaw's sRGB output space (`output_color=sRGB`, from the file's ColorMatrix; LibRaw
  uses one matrix whatever the light, see `g2r_jax.cli.convert`), the sRGB curve
  (`gamma=(2.4, 12.92)`: exponent 1/2.4 with a linear toe of slope 12.92, IEC 61966-2-1);
- demosaic: bilinear (`DemosaicAlgorithm.LINEAR`): the task works on binned images, where a
  better interpolation changes nothing a network could use, and it is about twice as fast as AHD
  on the small files (2 against 5 ms for 128 x 128 pixels on the development machine);
- highlights clipped (`HighlightMode.Clip`), no orientation flip (`user_flip=0`), 16-bit output,
  returned as float32 in [0, 1].

A file LibRaw cannot develop raises `DngError` naming it (the caller leaves it out and says so).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from g2r_jax.io.dng_info import DngError

__all__ = ["OPTIONS", "develop", "options"]

OPTIONS = {
    "use_camera_wb": True, "use_auto_wb": False, "no_auto_bright": True, "bright": 1.0,
    "output_color": "sRGB", "gamma": (2.4, 12.92), "demosaic_algorithm": "LINEAR",
    "highlight_mode": "Clip", "user_flip": 0, "output_bps": 16, "half_size": False,
}


def options() -> dict:
    """`OPTIONS` as rawpy's `postprocess` keyword arguments (its enums in place of the names).

    **Arguments:** none. **Returns:** a dict for `rawpy.RawPy.postprocess(**...)`.
    """
    import rawpy

    out = dict(OPTIONS)
    out["output_color"] = getattr(rawpy.ColorSpace, OPTIONS["output_color"])
    out["demosaic_algorithm"] = getattr(rawpy.DemosaicAlgorithm, OPTIONS["demosaic_algorithm"])
    out["highlight_mode"] = getattr(rawpy.HighlightMode, OPTIONS["highlight_mode"])
    return out


def develop(source, *, name: str | None = None) -> np.ndarray:
    """Develop one DNG with LibRaw at `OPTIONS`: its display-sRGB image.

    **Arguments:** `source`: a path, or the bytes of a DNG (e.g. `g2r_jax.io.dng_write.write_dng_bytes`;
    developed from memory, no file written); `name`: how errors name the file (default: the path,
    or '<dng bytes>').
    **Returns:** (H, W, 3) float32 in [0, 1], sRGB-coded (deterministic: equal files give equal
    arrays). **Raises:** `DngError(name, ...)` when LibRaw cannot open or develop the file.
    """
    import rawpy

    from g2r_jax.io.native_stderr import captured_native_stderr

    if isinstance(source, (bytes, bytearray, memoryview)):
        label, opened = name or "<dng bytes>", io.BytesIO(bytes(source))
    else:
        label, opened = name or str(source), str(Path(source))
    try:   # LibRaw prints its own complaints about damaged data: the DngError below says it
        with captured_native_stderr(lambda line: not line.startswith("g2r-")), rawpy.imread(opened) as raw:
            image = raw.postprocess(**options())
    except Exception as exc:  # rawpy.LibRawError and its subclasses, OSError, MemoryError, ...
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise DngError(label, f"LibRaw cannot develop it ({type(exc).__name__}: {text[:160]})") from None
    if image.ndim != 3 or image.shape[-1] != 3 or image.size == 0:
        raise DngError(label, f"LibRaw developed an image of shape {image.shape}, not (H, W, 3)")
    return (image.astype(np.float32) / np.float32(65535.0)).astype(np.float32)
