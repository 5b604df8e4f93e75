"""Rebuild the shipped profiles in this folder from ../shared/data (run from the repo root).

    python profiles/build_shipped_profiles.py

Where each number comes from is written into each profile's "provenance" field.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

from g2r_jax.cli.fit_profile import read_noise_table
from g2r_jax.profile.fitting import fit_profile
from g2r_jax.illuminants.distributions import neutral_to_chromaticity
from g2r_jax.io.dng_info import DngInfo
from g2r_jax.io.dng_read import read_dng_info
from g2r_jax.profile.schema import save_profile

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / ".." / "shared" / "data"
SOURCE = ("public repositories of Graphics2RAW (ICCV 2023) and Day-to-Night (CVPR 2022), "
          "Samsung AI Center Toronto, CC BY-NC 4.0")
# The NUS cameras' DNG layout (CFA, levels) is not part of the released matrices; these are
# placeholders for a 14-bit Bayer sensor, stated in each profile's provenance.
PLACEHOLDER_LAYOUT = dict(cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, 512.0), white_level=16383.0)
S20_CHOICE = "mixture"


def matrices_profiles(cameras: dict) -> None:
    for name, tags in cameras.items():
        if name.startswith("Samsung Galaxy S20") or name == "FujifilmXM1":
            continue  # S20 FE: its own night profile below; X-M1: X-Trans, not a Bayer sensor
        info = DngInfo(path=name, unique_camera_model=name, model=name, calibration_illuminants=(17, 21),
                       color_matrices=(np.reshape(tags["ColorMatrix_StandardLightA_tag17"], (3, 3)),
                                       np.reshape(tags["ColorMatrix_D65_tag21"], (3, 3))),
                       **PLACEHOLDER_LAYOUT)
        profile = fit_profile([info], name=name, illuminant_model="locus", provenance=(
            f"ColorMatrix1/2 (Standard Light A / D65, Adobe DNG Converter) of the {name} from the NUS "
            f"8-camera dataset as released in {SOURCE}. Illuminants: single-DNG CCT locus model "
            f"(Graphics2RAW supplement S3). CFA RGGB, black 512, white 16383 and no noise are "
            f"placeholders: only the matrices are known."))
        save_profile(profile, HERE / f"{name}.json")


def s20fe_night(cameras: dict) -> None:
    matrix = np.reshape(cameras["Samsung Galaxy S20 FE (main camera)"]["ColorMatrix_D65_tag21"], (3, 3))
    info = DngInfo(path="s20fe", unique_camera_model="Samsung Galaxy S20 FE main camera",
                   make="Samsung", model="Galaxy S20 FE", calibration_illuminants=(21,),
                   color_matrices=(matrix,), cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, 64.0),
                   white_level=1023.0)
    with open(DATA / "illuminants" / "s20fe_night_graycard_45.csv") as handle:
        rows = np.array([[float(r["r_over_g"]), float(r["g"]), float(r["b_over_g"])] for r in csv.DictReader(handle)])
    noise = read_noise_table(DATA / "noise" / "s20fe_heteroscedastic_gaussian.csv", info.black_level, info.white_level)
    profile = fit_profile([info], name="s20fe_night", illuminant_model=S20_CHOICE, noise=noise,
                          chromaticities=neutral_to_chromaticity(rows), provenance=(
        f"Samsung Galaxy S20 FE main camera at night. Illuminants: {S20_CHOICE} model fitted to the 45 "
        f"gray-card illuminants of s20fe_night_graycard_45.csv (sodium lamps kept), convex hull of all 45. "
        f"Colour: its D65 ColorMatrix (the only one released; one calibrated matrix). Noise: "
        f"s20fe_heteroscedastic_gaussian.csv (ISO 100-3200, per CFA position), black 64 / white 1023 as "
        f"stated there. CFA layout RGGB is an assumption (not in the data). Source: {SOURCE}."))
    save_profile(profile, HERE / "s20fe_night.json")


def gopro() -> None:
    path = DATA / "dng" / "gopro_hero6_GOPR0024.dng"
    info = read_dng_info(path)
    profile = fit_profile([info], name="gopro_hero6", illuminant_model="locus", provenance=(
        "All tags of the real GoPro HERO6 Black DNG gopro_hero6_GOPR0024.dng (gopro/gpr repository, "
        "Apache-2.0 or MIT): ColorMatrix1/2 for Tungsten/D50, CFA, levels, NoiseProfile. One DNG, so the "
        "single-DNG locus illuminant model (Graphics2RAW supplement S3)."))
    save_profile(profile, HERE / "gopro_hero6.json")


def main() -> int:
    if not DATA.exists():
        print(f"{DATA} not found: the shipped profiles are built from ../shared/data", file=sys.stderr)
        return 1
    cameras = json.loads((DATA / "cameras" / "color_matrices.json").read_text())
    matrices_profiles(cameras)
    s20fe_night(cameras)
    gopro()
    print("\n".join(sorted(p.name for p in HERE.glob("*.json"))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
