"""Convert the Gehler-Shi colour-constancy release to chart CSVs (`g2r_jax.charts` format).

Source (see ../shared/data/PROVENANCE.md): P. Gehler, C. Rother, A. Blake, T. Minka, T. Sharp,
"Bayesian Color Constancy Revisited", CVPR 2008; re-processed linear data by L. Shi and B. Funt
(`colourchecker_gamma1_bit12.mat`: raw RGB of the 24 ColorChecker patches in 568 images;
`real_illum_568.mat`: each image's measured illuminant; `folds.mat`: the standard 3-fold split).
Images 1-86: Canon EOS-1D (black level 0 in the release); 87-568: Canon EOS 5D, whose patch
values still carry the black level 129 (the release's own ground truth subtracts it, see
description.txt), while its illuminants are already black-subtracted. NaN patches (saturated or
too dark) are kept as NaN.

    python benchmarks/gehler_shi_charts.py [--data ../shared/data] -o OUT_DIR

writes OUT_DIR/gehler_shi_5d.csv and OUT_DIR/gehler_shi_1d.csv (column `fold`: the image's test
fold 0-2 of the standard split), and OUT_DIR/gehler_shi_5d.json / gehler_shi_1d.json: sensor
profiles with the camera's Adobe D65 ColorMatrix (../shared/data/cameras/gehler_shi_cameras.json),
its levels, RGGB (Canon), and a Gaussian illuminant model fitted to its measured illuminants.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from g2r_jax.colour.charts import ChartSet, write_charts  # noqa: E402
from g2r_jax.profile.fitting import fit_profile  # noqa: E402
from g2r_jax.illuminants.distributions import neutral_to_chromaticity  # noqa: E402
from g2r_jax.io.dng_info import DngInfo  # noqa: E402
from g2r_jax.profile.schema import save_profile  # noqa: E402

BLACK_5D = 129.0
CAMERAS = {"5d": ("Canon EOS 5D", slice(86, 568), BLACK_5D), "1d": ("Canon EOS-1D", slice(0, 86), 0.0)}


def load_release(folder: Path) -> dict:
    """The three .mat files as arrays: patches (568, 24, 3), illuminant (568, 3), names, folds (568,)."""
    from scipy.io import loadmat

    patches = np.asarray(loadmat(folder / "colourchecker_gamma1_bit12.mat")["real_rgb"], np.float64)
    illuminant = np.asarray(loadmat(folder / "real_illum_568.mat")["real_rgb"], np.float64)
    split = loadmat(folder / "folds.mat")
    names = [str(np.ravel(entry["name"])[0]).rsplit(".", 1)[0] for entry in np.ravel(split["Xfiles"])]
    folds = np.full(len(names), -1)
    for fold, test in enumerate(np.ravel(split["te_split"])):
        folds[np.ravel(test).astype(int) - 1] = fold   # 1-based image numbers
    if patches.shape != (568, 24, 3) or illuminant.shape != (568, 3) or np.any(folds < 0):
        raise ValueError(f"{folder}: unexpected Gehler-Shi release layout")
    return {"patches": patches, "illuminant": illuminant, "names": names, "folds": folds}


def charts_for(release: dict, camera: str) -> ChartSet:
    """One camera's charts, black removed (patches only; the illuminants already are)."""
    _, rows, black = CAMERAS[camera]
    return ChartSet(images=release["names"][rows], patches=release["patches"][rows] - black,
                    illuminant=release["illuminant"][rows], folds=release["folds"][rows],
                    source=f"Gehler-Shi {CAMERAS[camera][0]}")


def adobe_profile(cameras: dict, camera: str, charts: ChartSet):
    """Sensor profile of one Gehler-Shi camera from its Adobe D65 ColorMatrix (one matrix)."""
    name, _, black = CAMERAS[camera]
    tags = cameras[name]
    matrix = np.reshape(tags["color_matrix_d65"], (3, 3)) / float(tags["scale"])
    info = DngInfo(path=name, unique_camera_model=name, make="Canon", model=name, calibration_illuminants=(21,),
                   color_matrices=(matrix,), cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, black),
                   white_level=float(tags["white_level"]))
    return fit_profile([info], name=f"gehler_shi_{camera}", illuminant_model="gaussian",
                       chromaticities=neutral_to_chromaticity(charts.illuminant), provenance=(
        f"{name}: Adobe DNG Converter D65 ColorMatrix as tabulated in LibRaw (gehler_shi_cameras.json); "
        f"illuminants: Gaussian + hull of the {len(charts)} measured Gehler-Shi illuminants of this camera "
        f"(Gehler et al. CVPR 2008, Shi & Funt re-processing); CFA RGGB; black {black:g}, white "
        f"{tags['white_level']}; no noise model."))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "data"),
                        help="the shared data folder (default ../shared/data)")
    parser.add_argument("-o", "--out", required=True, help="output folder")
    args = parser.parse_args(argv)
    folder = Path(args.data) / "illuminants" / "gehler_shi"
    if not folder.is_dir():
        print(f"gehler_shi_charts: {folder}: no such folder", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    release = load_release(folder)
    cameras = json.loads((Path(args.data) / "cameras" / "gehler_shi_cameras.json").read_text())
    for camera in CAMERAS:
        charts = charts_for(release, camera)
        write_charts(out / f"gehler_shi_{camera}.csv", charts)
        save_profile(adobe_profile(cameras, camera, charts), out / f"gehler_shi_{camera}.json")
        print(f"{out / f'gehler_shi_{camera}.csv'}: {len(charts)} images, "
              f"{int(np.isnan(charts.patches).any(axis=2).sum())} NaN patches")
    return 0


if __name__ == "__main__":
    sys.exit(main())
