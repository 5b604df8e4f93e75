"""The spectral part of a sensor profile: the camera's sensitivities and its illuminant families.

`SpectralModel` is an equinox Module (a pytree: a `jit` argument like the rest of the profile):
- `sensitivities` (81, 3): the camera's R, G, B spectral sensitivity on `tables.WAVELENGTHS`,
  measured (rawtoaces / camspec / CSV) or estimated from the DNG matrices (`estimate.py`);
- `lamp_spectra` (F, 81): the lamp families (CIE FL*, LED-*, HP* tables) the profile's
  illuminant data demanded besides the Planckian/daylight locus (F may be 0).
On disk it is the optional `spectral` object of the profile JSON (lamp families by CIE name).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from g2r_jax.colour.spectral import tables


class SpectralModel(eqx.Module):
    sensitivities: Float[Array, "81 3"]
    lamp_spectra: Float[Array, "F 81"]
    lamp_families: tuple = eqx.field(static=True, default=())
    source: str = eqx.field(static=True, default="")
    estimated: bool = eqx.field(static=True, default=False)


def spectral_model(sensitivities, lamp_families=(), *, source: str = "", estimated: bool = False,
                   dtype=np.float32) -> SpectralModel:
    """Build a `SpectralModel` from (81, 3) sensitivities on the grid and lamp family names."""
    import jax

    dtype = jax.dtypes.canonicalize_dtype(dtype)
    sensitivities = np.asarray(sensitivities, np.float64)
    if sensitivities.shape != (len(tables.WAVELENGTHS), 3):
        raise ValueError(f"sensitivities must be ({len(tables.WAVELENGTHS)}, 3) on 380-780 nm at 5 nm, "
                         f"got {sensitivities.shape}")
    unknown = [name for name in lamp_families if name not in tables.LAMP_FAMILIES]
    if unknown:
        raise ValueError(f"unknown lamp families {unknown}; known: {', '.join(tables.LAMP_FAMILIES)}")
    lamps = (np.stack([tables.illuminant(n) for n in lamp_families]) if lamp_families
             else np.zeros((0, len(tables.WAVELENGTHS))))
    return SpectralModel(sensitivities=jnp.asarray(sensitivities, dtype), lamp_spectra=jnp.asarray(lamps, dtype),
                         lamp_families=tuple(lamp_families), source=source, estimated=estimated)


def spectral_to_dict(model: SpectralModel) -> dict:
    return {"wavelengths": tables.WAVELENGTHS.tolist(),
            "sensitivities": np.asarray(model.sensitivities, np.float64).round(6).tolist(),
            "sensitivities_source": model.source, "sensitivities_estimated": model.estimated,
            "illuminant_families": ["locus", *model.lamp_families]}


def spectral_from_dict(document, fail, dtype=np.float32) -> SpectralModel:
    """Validate the profile's `spectral` object; `fail(where, problem)` raises the profile error."""
    if not isinstance(document, dict):
        fail("spectral", "expected an object")
    wavelengths = np.asarray(document.get("wavelengths", []), np.float64)
    if wavelengths.shape != tables.WAVELENGTHS.shape or not np.allclose(wavelengths, tables.WAVELENGTHS):
        fail("spectral.wavelengths", "expected 380-780 nm at 5 nm (81 values)")
    try:
        values = np.asarray(document.get("sensitivities"), np.float64)
    except (TypeError, ValueError):
        fail("spectral.sensitivities", "expected numbers")
    if values.shape != (81, 3) or not np.all(np.isfinite(values)) or np.any(values.max(0) <= 0):
        fail("spectral.sensitivities", "expected 81 rows of three finite values, each channel non-zero")
    families = document.get("illuminant_families", ["locus"])
    if not isinstance(families, list) or "locus" not in families:
        fail("spectral.illuminant_families", "expected a list of names including 'locus'")
    lamps = [f for f in families if f != "locus"]
    try:
        return spectral_model(values, lamps, source=str(document.get("sensitivities_source", "")),
                              estimated=bool(document.get("sensitivities_estimated", False)), dtype=dtype)
    except ValueError as error:
        fail("spectral.illuminant_families", str(error))
