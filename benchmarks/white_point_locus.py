"""How far outside the CIE 1931 spectrum locus real light lands when solved through DNG matrices.

    PYTHONPATH=$PWD python benchmarks/white_point_locus.py [--data ../shared/data]

The margin of `g2r_jax.colour.spectrum_locus` (LOCUS_MARGIN) comes from this. Each light is seen
through a camera's measured spectral sensitivities (rawtoaces data, 380-780 nm) and its camera
neutral solved to a white point through the camera's Adobe DNG matrices (A and D65, from
cameras/color_matrices.json), as `g2r-fit-profile` does with a file's AsShotNeutral. Lights: the
115 CIE illuminants and light sources of colour-science (sodium, LED, fluorescent, metal halide,
daylight), and narrow-band light 20 nm wide (Gaussian) centred at 420-680 nm. Printed: the distance
outside the hull of the locus (<= 0 inside) of the farthest lights.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import colour
import jax.numpy as jnp
import numpy as np

from g2r_jax.colour import dng_model
from g2r_jax.colour.spectrum_locus import LOCUS_MARGIN, distance_outside_locus
from g2r_jax.runtime.x64 import enable_x64

CAMERAS = {"Canon600D": "Canon_EOS_600D", "Canon1DsMkIII": "Canon_EOS-1Ds_Mark_III"}


def camera(data: Path, name: str):
    matrices = json.loads((data / "cameras" / "color_matrices.json").read_text())[name]
    by_code = {code: np.reshape(matrices[key], (3, 3)) for key in matrices for code in (17, 21)
               if key.endswith(f"tag{code}")}
    model = dng_model.DngColourModel.from_tags((17, 21), (by_code[17], by_code[21]), dtype=np.float64)
    ssf = json.loads((data / "spectral" / "rawtoaces" / "camera" / f"{CAMERAS[name]}_380_780_5.json")
                     .read_text())["spectral_data"]["data"]["main"]
    keys = sorted(ssf, key=float)
    return model, np.array([float(k) for k in keys]), np.array([ssf[k] for k in keys], np.float64)


def outside(model, response) -> float:
    xy, _ = dng_model.camera_neutral_to_xy(jnp.asarray(response / response[1]), model)
    return distance_outside_locus(np.asarray(xy))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    args = parser.parse_args()
    lights = {**{f"CIE {k}": v for k, v in colour.SDS_ILLUMINANTS.items()},
              **{k: v for k, v in colour.SDS_LIGHT_SOURCES.items()}}
    print(f"LOCUS_MARGIN = {LOCUS_MARGIN}")
    with enable_x64():
        for name in CAMERAS:
            model, wavelengths, sensitivities = camera(args.data, name)
            lamps = []
            for label, sd in lights.items():
                power = np.interp(wavelengths, sd.wavelengths, sd.values, left=0.0, right=0.0)
                lamps.append((outside(model, power @ sensitivities), label))
            lamps.sort(reverse=True)
            bands = []
            for centre in range(420, 681, 10):
                power = np.exp(-0.5 * ((wavelengths - centre) / (20 / 2.355)) ** 2)
                bands.append((outside(model, power @ sensitivities), centre))
            bands.sort(reverse=True)
            print(f"{name}: {len(lamps)} lamps, farthest: " +
                  ", ".join(f"{label} {d:+.4f}" for d, label in lamps[:3]))
            print(f"{name}: 20-nm bands, farthest: " + ", ".join(f"{c} nm {d:+.4f}" for d, c in bands[:3]))


if __name__ == "__main__":
    main()
