"""Spectral tables on the one wavelength grid of the spectral model: 380-780 nm at 5 nm (81 samples,
the CIE tables' own spacing: a 10 nm grid misses the lines of fluorescent and sodium lamps).

Every CIE table (colour-matching functions, illuminants D65, A, FL*, LED-*, HP*, the CIE daylight
basis through `sd_CIE_illuminant_D_series`, Planck's law through `sd_blackbody`), the ColorChecker
reflectances (Ohta) and the Mallett-Yuksel sRGB basis come from colour-science, resampled to the
grid with its own interpolation (`SpectralDistribution.align`); nothing is retyped. numpy, built once.
"""

from __future__ import annotations

import functools

import numpy as np

from g2r_jax.io.spectral_grid import WAVELENGTHS, resample  # noqa: F401  (the grid is defined where it is read)
from g2r_jax.io.spectral_grid import spectral_shape as _shape

OBSERVER = "CIE 1931 2 Degree Standard Observer"
LAMP_FAMILIES = ("FL2", "FL11", "LED-B3", "LED-B1", "HP1", "HP2")  # CIE 15:2018 tables in colour-science
LOCUS_MIRED = np.linspace(1e6 / 25000.0, 1e6 / 1500.0, 128)   # table of the locus spectra


@functools.lru_cache(maxsize=None)
def cmfs() -> np.ndarray:
    """CIE 1931 2-degree colour-matching functions on the grid, (81, 3)."""
    import colour

    return np.asarray(colour.MSDS_CMFS[OBSERVER].copy().align(_shape()).values, np.float64)


@functools.lru_cache(maxsize=None)
def illuminant(name: str) -> np.ndarray:
    """A CIE illuminant of colour-science (D65, A, FL2, LED-B3, HP1...) on the grid, max 1."""
    import colour

    if name not in colour.SDS_ILLUMINANTS:
        raise ValueError(f"unknown illuminant {name!r}")
    values = np.asarray(colour.SDS_ILLUMINANTS[name].copy().align(_shape()).values, np.float64)
    return values / values.max()


def blackbody(cct: float) -> np.ndarray:
    """Planck's law at `cct` kelvin on the grid (colour.sd_blackbody), max 1."""
    import colour

    values = np.asarray(colour.sd_blackbody(float(cct), _shape()).values, np.float64)
    return values / values.max()


def daylight(cct: float) -> np.ndarray:
    """CIE daylight (D series) of correlated colour temperature `cct` on the grid, max 1."""
    import colour

    xy = colour.temperature.CCT_to_xy_CIE_D(float(cct))
    values = np.asarray(colour.sd_CIE_illuminant_D_series(xy).copy().align(_shape()).values, np.float64)
    return values / values.max()


def locus_spectrum(cct: float) -> np.ndarray:
    """The white light of the project's locus at `cct` (`g2r_jax.colour.CCT_to_xy`): Planck below
    4000 K, CIE daylight above 5000 K, the same smoothstep blend in between; max 1."""
    blend = np.clip((cct - 4000.0) / 1000.0, 0.0, 1.0)
    blend = blend * blend * (3 - 2 * blend)
    planck = blackbody(cct)
    values = (1 - blend) * planck + blend * (daylight(max(cct, 4000.0)) if blend > 0 else planck)
    return values / values.max()


@functools.lru_cache(maxsize=None)
def locus_table() -> np.ndarray:
    """Locus spectra at `LOCUS_MIRED` (128, 81), for linear interpolation in mired under jit."""
    return np.stack([locus_spectrum(1e6 / m) for m in LOCUS_MIRED])


@functools.lru_cache(maxsize=None)
def colour_checker() -> np.ndarray:
    """The 24 ColorChecker reflectances (N. Ohta, in colour-science) on the grid, (24, 81),
    in the standard patch order (18 chromatic, then 6 neutral)."""
    import colour

    patches = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    return np.stack([np.asarray(sd.copy().align(_shape()).values, np.float64) for sd in patches.values()])


@functools.lru_cache(maxsize=None)
def mallett_yuksel_basis() -> np.ndarray:
    """The three sRGB basis reflectances of Mallett & Yuksel, "Spectral Primary Decomposition for
    Rendering with sRGB Reflectance" (EGSR 2019), on the grid, (81, 3): reflectance = basis @ rgb
    for linear sRGB rgb in [0, 1]; the rows sum to 1 (white -> a flat 100 % reflector)."""
    from colour.recovery import MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019

    return np.asarray(MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019.copy().align(_shape()).values, np.float64)


def tristimulus(spectra, light) -> np.ndarray:
    """CIE XYZ of reflectances (..., 81) under `light` (81,), Y of the perfect white = 1."""
    weights = cmfs() * np.asarray(light)[:, None]
    return np.asarray(spectra) @ weights / weights[:, 1].sum()
