"""Build the spectral model's shipped tables from the published measurements (offline).

    python -m g2r_jax.colour.spectral.build_tables --data ../shared/data [--lattice 9]

writes `g2r_jax/spectral/data/sensitivity_basis.json` (per-channel PCA basis of the measured
camera sensitivities: rawtoaces-data (Academy, Apache-2.0) and camspec (Jiang et al., WACV 2013,
CC BY-NC-SA 4.0)) and `data/jakob_hanika_lattice.json` (Jakob-Hanika coefficients at the nodes of a
lattice over linear sRGB, by colour-science's optimiser). Also the leave-one-out check of the
estimate from matrices (`leave_one_out`), used by benchmarks/spectral_colour.py.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from g2r_jax.colour.spectral import tables
from g2r_jax.colour.spectral.estimate import (
    BASIS_PATH,
    PRIOR_WEIGHT,
    build_basis,
    calibration_light,
    estimate_from_matrices)
from g2r_jax.colour.spectral.upsampling import LATTICE_PATH, jakob_hanika_coefficients_for_srgb

_WORDS = re.compile(r"\b(eos|digital|ilce|dsc|dc)\b")


def camera_key(name: str) -> str:
    """A name that is the same for one camera in both sources ('Canon EOS 600D' ~ 'Canon 600D')."""
    return re.sub(r"[^a-z0-9]", "", _WORDS.sub("", name.lower().replace("-", " ").replace("_", " ")))


def published_sensitivities(data_dir) -> list[tuple[str, str, np.ndarray]]:
    """[(key, 'source: name', (81, 3))] of every camera in ../shared/data/spectral."""
    from g2r_jax.io.sensitivities import read_camspec, read_rawtoaces_json

    data_dir = Path(data_dir) / "spectral"
    found = []
    for path in sorted((data_dir / "rawtoaces" / "camera").glob("*.json")):
        s = read_rawtoaces_json(path)
        found.append((camera_key(s.camera), f"rawtoaces: {s.camera}", s.values))
    for name, s in read_camspec(data_dir / "camspec" / "camspec_database.txt").items():
        found.append((camera_key(name), f"camspec: {name}", s.values))
    return found


def training_reflectances(data_dir) -> np.ndarray:
    """The 190 rawtoaces training reflectances on the grid (for synthesising matrices)."""
    document = json.loads((Path(data_dir) / "spectral/rawtoaces/training/training_spectral.json").read_text())
    table = document["spectral_data"]["data"]["main"]
    rows = sorted((float(k), v) for k, v in table.items())
    return tables.resample([w for w, _ in rows], [v for _, v in rows], outside=None).T


def synthetic_matrix(sensitivities, light, reflectances) -> np.ndarray:
    """XYZ -> camera 3x3 by least squares over `reflectances` under `light`, as a calibration would."""
    xyz = tables.tristimulus(reflectances, light)
    camera = reflectances @ (light[:, None] * sensitivities)
    solution, *_ = np.linalg.lstsq(xyz, camera, rcond=None)
    return solution.T


def spectral_angle(a, b) -> np.ndarray:
    """Angle (degrees) between two sensitivity curves, per channel."""
    cosine = np.sum(a * b, 0) / (np.linalg.norm(a, axis=0) * np.linalg.norm(b, axis=0))
    return np.degrees(np.arccos(np.clip(cosine, -1, 1)))


def leave_one_out(data_dir, *, n_components: int = 6, prior_weight: float = PRIOR_WEIGHT) -> list[dict]:
    """For every camera: basis from all other cameras (both sources' copies held out), matrices
    synthesised for A and D65 from its measured sensitivities on the 190 training reflectances,
    estimate from those matrices; the spectral angle per channel to the measured curves."""
    sets = published_sensitivities(data_dir)
    reflectances = training_reflectances(data_dir)
    lights = [calibration_light(17), calibration_light(21)]
    results = []
    for key, name, values in sets:
        others = np.stack([v for k, _, v in sets if k != key])
        basis = build_basis(others, n_components)
        matrices = [synthetic_matrix(values, light, reflectances) for light in lights]
        estimate = estimate_from_matrices(lights, matrices, basis, prior_weight=prior_weight)
        results.append({"camera": name, "key": key, "angle": spectral_angle(estimate, values),
                        "estimate": estimate, "truth": values})
    return results


def write_basis(data_dir, n_components: int = 6) -> None:
    from g2r_jax.io.atomic import atomic_write_bytes

    sets = published_sensitivities(data_dir)
    basis = build_basis(np.stack([v for _, _, v in sets]), n_components)
    document = {
        "about": "Per-channel PCA basis (mean + components, variances) of measured camera spectral "
                 "sensitivities on 380-780 nm at 5 nm, each camera normalised to green peak 1; "
                 "g2r_jax.colour.spectral.build_tables.",
        "source": f"{len(sets)} measured sets: rawtoaces-data camera/*.json (Academy Software Foundation, "
                  "Apache-2.0) and camspec_database.txt (Jiang, Liu, Gu, Suesstrunk, WACV 2013, CC BY-NC-SA 4.0)",
        "cameras": [name for _, name, _ in sets],
        "wavelengths": tables.WAVELENGTHS.tolist(),
        "mean": np.round(basis["mean"], 7).tolist(),
        "components": np.round(basis["components"], 7).tolist(),
        "variances": np.round(basis["variances"], 9).tolist(),
    }
    atomic_write_bytes(BASIS_PATH, (json.dumps(document) + "\n").encode())


def write_lattice(n: int) -> None:
    from g2r_jax.io.atomic import atomic_write_bytes

    nodes = np.linspace(0.0, 1.0, n)
    grid = np.stack(np.meshgrid(nodes, nodes, nodes, indexing="ij"), -1).reshape(-1, 3)
    coefficients = jakob_hanika_coefficients_for_srgb(grid)
    document = {
        "about": "Jakob & Hanika (2019) sigmoid-polynomial coefficients (1/nm^2, 1/nm, 1) at the nodes of an "
                 f"{n}^3 lattice over linear sRGB [0, 1]^3 (index order r, g, b), fitted to each node's XYZ under "
                 "D65 (CIE 1931) by colour-science's find_coefficients_Jakob2019; g2r_jax.colour.spectral.build_tables.",
        "nodes": nodes.tolist(),
        "coefficients": np.asarray(coefficients).tolist(),
    }
    atomic_write_bytes(LATTICE_PATH, (json.dumps(document) + "\n").encode())


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--components", type=int, default=6)
    parser.add_argument("--lattice", type=int, default=9, help="Jakob-Hanika lattice size per axis (0: skip)")
    args = parser.parse_args(argv)
    write_basis(args.data, args.components)
    print(f"wrote {BASIS_PATH}")
    if args.lattice:
        write_lattice(args.lattice)
        print(f"wrote {LATTICE_PATH}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
