"""sRGB -> reflectance spectra ("spectral upsampling"), two methods.

- Linear three-basis (Mallett & Yuksel, "Spectral Primary Decomposition for Rendering with sRGB
  Reflectance", EGSR 2019): reflectance = B @ rgb with three basis spectra B (colour-science's
  table). Linear in rgb, so the camera response under light L is one 3x3 per image:
  S^T diag(L) B. This is the default of `colour="spectral"`.
- Sigmoid polynomial (Jakob & Hanika, "A Low-Dimensional Function Space for Efficient Spectral
  Upsampling", Computer Graphics Forum 2019): reflectance(lambda) = s(c0 lambda^2 + c1 lambda + c2),
  s(x) = 1/2 + x / (2 sqrt(1 + x^2)); the coefficients of a colour are found by colour-science's
  optimiser (`find_coefficients_Jakob2019`). For images, coefficients at the nodes of a lattice
  over linear sRGB [0, 1]^3 are a small shipped table (`data/jakob_hanika_lattice.json`, built by
  `python -m g2r_jax.colour.spectral.build_tables`); per image the camera response of every node is
  computed (nodes x 81 x 3) and pixels interpolate it trilinearly.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from g2r_jax.colour.spectral import tables

LATTICE_PATH = Path(__file__).resolve().parent / "data" / "jakob_hanika_lattice.json"


def sigmoid_polynomial(coefficients, wavelengths=tables.WAVELENGTHS):
    """Jakob & Hanika (2019) eq. 3 with dimensional coefficients (1/nm^2, 1/nm, 1): (..., 81)."""
    wl = jnp.asarray(wavelengths, jnp.result_type(coefficients, jnp.float32))
    c = jnp.asarray(coefficients)
    x = c[..., 0:1] * wl**2 + c[..., 1:2] * wl + c[..., 2:3]
    return 0.5 + x / (2.0 * jnp.sqrt(1.0 + x * x))


def jakob_hanika_spectra(coefficients) -> np.ndarray:
    coefficients = np.asarray(coefficients, np.float64)
    x = coefficients[..., 0:1] * tables.WAVELENGTHS**2 + coefficients[..., 1:2] * tables.WAVELENGTHS + coefficients[..., 2:3]
    return 0.5 + x / (2.0 * np.sqrt(1.0 + x * x))


def jakob_hanika_coefficients_for_srgb(srgb, *, warm_start=None) -> np.ndarray:
    """Dimensional coefficients (N, 3) for linear sRGB colours (N, 3), fitted to their XYZ under
    D65 with colour-science's `find_coefficients_Jakob2019` (CIE 1931 observer). Colours outside
    the sigmoid's reach (saturated gamut corners) get the optimiser's closest spectrum."""
    import colour
    from colour.recovery.jakob2019 import SPECTRAL_SHAPE_JAKOB2019, dimensionalise_coefficients, find_coefficients_Jakob2019

    from g2r_jax.colour.conversions import MATRIX_SRGB_TO_XYZ

    srgb = np.atleast_2d(np.asarray(srgb, np.float64))
    cmfs = colour.MSDS_CMFS[tables.OBSERVER].copy().align(SPECTRAL_SHAPE_JAKOB2019)
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(SPECTRAL_SHAPE_JAKOB2019)
    result = []
    start = np.zeros(3) if warm_start is None else np.asarray(warm_start, np.float64)
    for rgb in srgb:
        XYZ = np.clip(rgb, 1e-4, 1 - 1e-4) @ MATRIX_SRGB_TO_XYZ.T
        dimensionless, _ = find_coefficients_Jakob2019(XYZ, cmfs, d65, start, dimensionalise=False)
        result.append(dimensionalise_coefficients(dimensionless, SPECTRAL_SHAPE_JAKOB2019))
        if warm_start is not None:
            start = dimensionless
    return np.stack(result)


@functools.lru_cache(maxsize=1)
def lattice() -> tuple[np.ndarray, np.ndarray]:
    """The shipped Jakob-Hanika lattice: node positions (n,) per axis and reflectances
    (n, n, n, 81) on the spectral grid (from the stored coefficients)."""
    if not LATTICE_PATH.exists():
        raise FileNotFoundError(f"{LATTICE_PATH}: missing; build it with python -m g2r_jax.colour.spectral.build_tables")
    document = json.loads(LATTICE_PATH.read_text())
    nodes = np.asarray(document["nodes"], np.float64)
    coefficients = np.asarray(document["coefficients"], np.float64).reshape(len(nodes), len(nodes), len(nodes), 3)
    return nodes, jakob_hanika_spectra(coefficients)


def trilinear(table, rgb, nodes):
    """Interpolate `table` (n, n, n, C) at rgb (..., 3) in [0, 1] on a lattice with `nodes` (n,)
    evenly spaced from 0 to 1 (values outside are clamped). Returns (..., C)."""
    n = nodes.shape[0]
    position = jnp.clip(rgb, 0.0, 1.0) * (n - 1)
    low = jnp.clip(jnp.floor(position).astype(jnp.int32), 0, n - 2)
    f = position - low
    out = 0.0
    for corner in range(8):
        dr, dg, db = (corner >> 2) & 1, (corner >> 1) & 1, corner & 1
        weight = ((f[..., 0] if dr else 1 - f[..., 0]) * (f[..., 1] if dg else 1 - f[..., 1])
                  * (f[..., 2] if db else 1 - f[..., 2]))
        out = out + weight[..., None] * table[low[..., 0] + dr, low[..., 1] + dg, low[..., 2] + db]
    return out
