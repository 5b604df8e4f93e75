"""The one wavelength grid of spectral data in g2r_jax, and resampling onto it.

380-780 nm at 5 nm: 81 samples, the CIE tables' own spacing (a 10 nm grid misses the lines of
fluorescent and sodium lamps). Read side inputs (camera sensitivities, `g2r_jax.io.sensitivities`)
are resampled onto it where they are read; the spectral model's tables
(`g2r_jax.colour.spectral.tables`) use the same grid. Interpolation: colour-science's own
(`SpectralDistribution.align`: Sprague for uniform data, cubic spline otherwise).
"""

from __future__ import annotations

import numpy as np

__all__ = ["WAVELENGTHS", "spectral_shape", "resample"]

WAVELENGTHS = np.arange(380.0, 781.0, 5.0)     # nm; 81 samples


def spectral_shape():
    """The grid as a colour-science SpectralShape."""
    import colour

    return colour.SpectralShape(WAVELENGTHS[0], WAVELENGTHS[-1], WAVELENGTHS[1] - WAVELENGTHS[0])


def resample(wavelengths, values, *, outside: float | None = 0.0) -> np.ndarray:
    """Values sampled at `wavelengths` (N,) or (N, C) -> the grid (81,) or (81, C), by
    colour-science's interpolation (Sprague / cubic spline); outside the measured range the value
    is `outside` (0: a sensitivity measured from 400 nm has nothing below), or the end value if None."""
    import colour

    wavelengths = np.asarray(wavelengths, np.float64)
    values = np.asarray(values, np.float64)
    extrapolation = ({"method": "Constant"} if outside is None
                     else {"method": "Constant", "left": outside, "right": outside})
    kind = colour.SpectralDistribution if values.ndim == 1 else colour.MultiSpectralDistributions
    data = kind(values, wavelengths, extrapolator_kwargs=extrapolation)
    return np.asarray(data.copy().align(spectral_shape()).values, np.float64)
