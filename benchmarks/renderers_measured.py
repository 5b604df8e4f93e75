"""Which RAW developers render g2r_jax's DNGs as written: each measured on the same patch scene.

What it measures: g2r_jax writes two (sometimes three) ColorMatrix tags, one per calibration
illuminant; the DNG specification interpolates them by the colour temperature of the white that
AsShotNeutral gives. For each developer, profile and colour temperature, the mean CIEDE2000
between the developer's rendering and the input colours, after one global exposure scale.

How (`tests/renderer_helpers.py`): the 24 flat ColorChecker patches of `tests/dng_reference.py`
(`patch_scene`, 8-bit sRGB PNG, enlarged 4x: 64-pixel patches, boxes 12 pixels inside each) are
converted by `g2r-convert --no-noise --no-content-model --illuminants CSV`, the CSV giving the
camera neutral of the white at that temperature under the profile's matrices. Each developer
renders the DNG; each box's mean goes to XYZ (D65) from the developer's output space; the
patches kept are those below 0.8 linear in the input (the white patch is out) and below 0.95 of
the white level in the raw and after white balance (22 of 24 here); `mean_delta_E_2000` fits one
exposure scale on Y and averages CIEDE2000 against the input's XYZ. Output size and orientation
are checked (the white patch must come out brightest; RawTherapee's 4-pixel border crop is
allowed for).

Developers and their exact settings:
- `model` (control): the DNG colour model of colour_hdri (`dng_reference.render_patches_to_XYZ_D65`)
  on each box's mean raw values (rawpy): matrices interpolated by the white's temperature,
  Bradford to D65.
- `one_matrix` (prediction, no program): what a developer that uses one ColorMatrix gives, by
  dcraw's method: camera RGB / AsShotNeutral, then the inverse of (ColorMatrix of the highest
  calibration temperature x sRGB->XYZ, rows scaled to sum 1), as linear sRGB.
- `adobe_sdk`: Adobe's DNG SDK 1.7.1 (the libdng of the `dngpy` wheel) through
  `benchmarks/dng_sdk_render.cpp` (build: `benchmarks/dng_sdk_padding.py`; give it with
  `--sdk-render PATH` or `$G2R_SDK_RENDER`): `dng_render` at its defaults (white from
  AsShotNeutral), final space ProPhoto, float pixels, identity tone curve. The default Shadows 5
  (a black point at 0.005 of white with a quadratic toe) and ProPhoto's gamma-1.8 encode are
  inverted exactly (`renderer_helpers.undo_sdk_encoding`), then ProPhoto (D50) -> XYZ -> Bradford D65.
- `libraw`: LibRaw 0.22.2 through rawpy `postprocess` at `g2r_jax.io.reference_render.options()`
  with gamma (1, 1): use_camera_wb=True, use_auto_wb=False, no_auto_bright=True, bright=1,
  output_color=sRGB, demosaic LINEAR, highlight_mode Clip, user_flip=0, output_bps=16.
- `darktable`: `darktable-cli IN.dng OUT.tif --icc-type LIN_REC709 --core --configdir TMP/dt_config
  --cachedir TMP/dt_cache --library :memory: --conf plugins/darkroom/workflow=none --conf
  plugins/imageio/format/tiff/bpp=32 --conf plugins/darkroom/chromatic-adaptation=legacy`, no
  sidecar: history rawprepare, demosaic, colorin (standard colour matrix), colorout, gamma,
  temperature (camera white balance), highlights, flip; no exposure, filmic or base curve.
  `darktable_modern`: the same with `chromatic-adaptation=modern` (darktable 4.2's default:
  white balance at the camera's D65 reference, then color calibration from the as-shot white).
  Linear Rec.709 float TIFF, decoded through its embedded ICC profile.
- `rawtherapee`: `rawtherapee-cli -q -o OUT.tif -t -b32 -Y -p colorimetric.pp3 -c IN.dng` with
  HOME, RT_SETTINGS, RT_CACHE, XDG_CONFIG_HOME and XDG_CACHE_HOME in a temporary folder, no
  `-d` (RawTherapee's neutral profile: no auto exposure, curves or sharpening) and the pp3
  `renderer_helpers.RAWTHERAPEE_PP3`: [White Balance] Setting=Camera; [Color Management]
  InputProfile=(camera) (the "Camera standard" matrix), ToneCurve=false, ApplyLookTable=false,
  ApplyHueSatMap=false, WorkingProfile=ProPhoto, OutputProfile=RTv4_sRGB. 32-bit float TIFF,
  decoded through its embedded ICC profile (sRGB curve, parametric type 4).
A developer that is absent is skipped with a line saying why.

Command (about a minute on 2 cores):
    nice -n 10 python benchmarks/renderers_measured.py --sdk-render /path/to/sdk_render \\
        --profiles NikonD5200,Canon600D,gopro_hero6 --ccts 2850,4300,6500 --json out.json --markdown out.md
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import renderer_helpers as rh  # noqa: E402


def parse_arguments(argv=None) -> argparse.Namespace:
    """The command line (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--profiles", default="NikonD5200,Canon600D,gopro_hero6",
                        help="shipped profiles, comma-separated (two-matrix profiles: the control is colour_hdri's)")
    parser.add_argument("--ccts", default="2850,4300,6500", help="colour temperatures in kelvin, comma-separated")
    parser.add_argument("--developers", default=",".join(rh.DEVELOPERS), help="subset of " + ",".join(rh.DEVELOPERS))
    parser.add_argument("--sdk-render", help=f"the sdk_render program (else ${rh.SDK_RENDER_ENV} or the PATH)")
    parser.add_argument("--json", help="write the figures here")
    parser.add_argument("--markdown", help="write the table here")
    return parser.parse_args(argv)


def versions() -> str:
    """The developers' versions found here, one line."""
    import subprocess

    import rawpy

    found = [f"LibRaw {'.'.join(map(str, rawpy.libraw_version))} (rawpy {rawpy.__version__})"]
    for program, option in (("darktable-cli", "--version"), ("rawtherapee-cli", "-h")):
        try:
            text = subprocess.run([program, option], capture_output=True, text=True, timeout=60).stdout
            first = next(line.strip() for line in text.splitlines() if line.strip())   # names the version
            found.append(first.removeprefix("this is ").removesuffix(", command line."))
        except (OSError, StopIteration, subprocess.SubprocessError):
            found.append(f"{program}: absent")
    program = rh.sdk_render_program()
    if program:
        try:   # the libdng sdk_render links: the dngpy wheel's (benchmarks/dng_sdk_padding.py)
            import dngpy

            library = sorted((Path(dngpy.__file__).parents[1] / "lib").glob("libdng.so.*.*"))
        except ImportError:
            library = []
        found.append(f"sdk_render {program}" + (f" (dngpy's {library[-1].name})" if library else ""))
    return "; ".join(found)


def available(developers) -> list:
    """The developers that can run here; prints a line for each one skipped."""
    present = []
    for developer in developers:
        reason = rh.missing(developer)
        if reason:
            print(f"skipped: {developer} ({rh.LABELS[developer]}): {reason}", flush=True)
        else:
            present.append(developer)
    return present


def run(profiles, ccts, developers, folder: Path) -> list:
    """Convert the scene for every (profile, CCT) and measure every developer on it.

    **Returns:** rows {"developer", "profile", "cct", "delta_E", "max_delta_E", "patches", "scale"}
    or, for a rendering that failed, {"developer", "profile", "cct", "error"}.
    """
    scene, codes, boxes = rh.enlarged_patch_scene(folder)
    rows = []
    for profile in profiles:
        for cct in ccts:
            dng = rh.convert_scene(scene, profile, cct, folder / f"{profile}_{cct}")
            for developer in developers:
                row = {"developer": developer, "profile": profile, "cct": cct}
                try:
                    row.update(rh.measure(developer, dng, codes, boxes, folder / f"{profile}_{cct}_{developer}"))
                except Exception as exc:  # one developer failing on one file is a result, not a stop
                    row["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
                rows.append(row)
                shown = row.get("error") or f"{row['delta_E']:.3f} (max {row['max_delta_E']:.2f}, {row['patches']} patches)"
                print(f"  {profile:12} {cct:5} K  {developer:17} {shown}", flush=True)
    return rows


def table(rows, profiles, ccts, developers) -> str:
    """Markdown table: one row per developer and profile, one column per CCT (mean dE00)."""
    lookup = {(r["developer"], r["profile"], r["cct"]): r for r in rows}
    lines = ["| developer | profile | " + " | ".join(f"{c} K" for c in ccts) + " |",
             "|---|---|" + "---:|" * len(ccts)]
    for developer in developers:
        for profile in profiles:
            cells = []
            for cct in ccts:
                row = lookup.get((developer, profile, cct))
                cells.append("failed" if row is None or "error" in row else f"{row['delta_E']:.3f}")
            lines.append(f"| {rh.LABELS[developer]} | {profile} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    """Measure, print the table, write the JSON and Markdown files asked for."""
    args = parse_arguments(argv)
    if args.sdk_render:
        os.environ[rh.SDK_RENDER_ENV] = str(Path(args.sdk_render).resolve())
    profiles = [p for p in args.profiles.split(",") if p]
    ccts = [int(c) for c in args.ccts.split(",") if c]
    print(versions(), flush=True)
    developers = available([d for d in args.developers.split(",") if d])
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="g2r_renderers_") as tmp:
        rows = run(profiles, ccts, developers, Path(tmp))
    text = table(rows, profiles, ccts, developers)
    print(f"\nmean CIEDE2000 against the input, unclipped patches, one exposure scale "
          f"({time.perf_counter() - start:.0f} s)\n\n{text}")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "labels": rh.LABELS}, indent=1))
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")
    return 0 if not any("error" in r for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
