"""Camera spectral sensitivities estimated from the DNG colour matrices alone.

A low-dimensional basis of camera sensitivities (per channel: mean + principal components, PCA
over the published measured sets: rawtoaces and camspec, see `build_tables.py`) is shipped as
derived numbers (`data/sensitivity_basis.json`, with its sources). For a camera known only by its
ColorMatrix tags (XYZ -> camera, one per calibration illuminant I), the estimate is the
basis combination that best reproduces, for the 24 ColorChecker reflectances r under I,

    S^T diag(I) r  ~  k_I * ColorMatrix_I * XYZ_I(r)        (one free scale k_I per matrix)

with a Gaussian prior on the coefficients (their PCA variances): a linear least-squares (MAP)
problem. The DNG spec's ColorMatrix maps XYZ to camera values for the calibration illuminant, so
this is the spectral statement of what the matrices say. numpy; runs once per profile.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np

from g2r_jax.colour.spectral import tables

BASIS_PATH = Path(__file__).resolve().parent / "data" / "sensitivity_basis.json"
PRIOR_WEIGHT = 100.0        # multiplies the prior precision; see README "Spectral sensor model" for the choice
ILLUMINANT_SPECTRUM = {17: "A", 21: "D65", 23: "D50", 20: "D55", 22: "D75", 3: "A", 24: "A", 2: "FL2",
                       14: "FL2", 12: "FL1", 13: "FL8", 15: "FL3", 16: "FL4", 19: "C", 18: "B", 1: "D55",
                       4: "D55", 9: "D55", 10: "D65", 11: "D75"}


@functools.lru_cache(maxsize=1)
def shipped_basis() -> dict:
    document = json.loads(BASIS_PATH.read_text())
    return {"mean": np.asarray(document["mean"], np.float64),                 # (81, 3)
            "components": np.asarray(document["components"], np.float64),     # (3, K, 81)
            "variances": np.asarray(document["variances"], np.float64),       # (3, K)
            "source": document["source"]}


def build_basis(sensitivity_sets, n_components: int = 6) -> dict:
    """Per-channel PCA of (N, 81, 3) sensitivities (each normalised to green peak 1)."""
    data = np.asarray(sensitivity_sets, np.float64)
    mean = data.mean(0)
    components, variances = [], []
    for c in range(3):
        centred = data[:, :, c] - mean[:, c]
        _, singular, vt = np.linalg.svd(centred, full_matrices=False)
        components.append(vt[:n_components])
        variances.append(singular[:n_components] ** 2 / max(len(data) - 1, 1))
    return {"mean": mean, "components": np.stack(components), "variances": np.stack(variances)}


def calibration_light(code: int) -> np.ndarray:
    """The spectrum of an EXIF LightSource code (CIE table), else the locus light at its DNG CCT."""
    from g2r_jax.colour.dng_model import calibration_illuminant_cct

    name = ILLUMINANT_SPECTRUM.get(int(code))
    return tables.illuminant(name) if name is not None else tables.locus_spectrum(calibration_illuminant_cct(code))


def estimate_from_matrices(lights, matrices, basis=None, *, prior_weight: float = PRIOR_WEIGHT,
                           reflectances=None) -> np.ndarray:
    """(81, 3) sensitivities (green peak 1) whose responses best match the matrices.

    **Arguments:** `lights`: the calibration illuminants' spectra (81,) (`calibration_light`);
    `matrices`: their XYZ -> camera ColorMatrix (3, 3) each; `basis`: `build_basis` result
    (default: shipped); `reflectances` (N, 81): the surfaces of the fit (default: ColorChecker).
    """
    basis = shipped_basis() if basis is None else basis
    reflectances = tables.colour_checker() if reflectances is None else np.asarray(reflectances)
    mean, components, variances = basis["mean"], basis["components"], basis["variances"]
    k = components.shape[1]
    n_matrices = len(matrices)
    rows, targets = [], []
    for i, (light, matrix) in enumerate(zip(lights, matrices)):
        weighted = reflectances * light                                    # (N, 81)
        xyz = tables.tristimulus(reflectances, light)                      # (N, 3), white Y = 1
        predicted = xyz @ np.asarray(matrix, np.float64).T                 # (N, 3) camera per the matrix
        scale = 1.0 / np.abs(predicted).max()
        for c in range(3):
            # unknowns: K coefficients per channel, then one scale per matrix
            row = np.zeros((len(reflectances), 3 * k + n_matrices))
            row[:, c * k:(c + 1) * k] = weighted @ components[c].T * scale
            row[:, 3 * k + i] = -predicted[:, c] * scale
            rows.append(row)
            targets.append(-(weighted @ mean[:, c]) * scale)
    A = np.concatenate(rows)
    b = np.concatenate(targets)
    prior = np.zeros(3 * k + n_matrices)
    prior[:3 * k] = prior_weight / np.maximum(variances.reshape(-1), 1e-12) * 1e-3
    solution = np.linalg.solve(A.T @ A + np.diag(prior), A.T @ b)
    coefficients = solution[:3 * k].reshape(3, k)
    estimate = mean + np.einsum("ck,ckw->wc", coefficients, components)
    estimate = np.clip(estimate, 0.0, None)
    return estimate / estimate[:, 1].max()


def estimate_sensitivities(colour_model) -> tuple[np.ndarray, str]:
    """Sensitivities of a profile's camera from its `DngColourModel` (each ColorMatrix with
    CameraCalibration and AnalogBalance applied, as the DNG spec's XYZtoCamera, under its own
    calibration illuminant's spectrum), and the provenance line."""
    ccts = np.asarray(colour_model.calibration_cct, np.float64)
    matrices = (np.asarray(colour_model.analog_balance, np.float64)[None, :, None]
                * np.asarray(colour_model.camera_calibration, np.float64)) @ np.asarray(colour_model.color_matrix, np.float64)
    codes = tuple(getattr(colour_model, "calibration_illuminants", ()) or ())
    n = len(codes) if codes else (1 if np.allclose(matrices[0], matrices[-1]) else len(matrices))
    codes = codes or (0,) * n
    lights = [calibration_light(code) if int(code) in ILLUMINANT_SPECTRUM else tables.locus_spectrum(float(cct))
              for code, cct in zip(codes, ccts[:n])]
    estimate = estimate_from_matrices(lights, matrices[:n])
    source = (f"estimated from {n} ColorMatrix tag(s) with the shipped basis "
              f"({shipped_basis()['source']})")
    return estimate, source
