"""Profiles edited by measurement: each function returns a copy of a `SensorProfile` with one part
replaced by what was measured or estimated (the fits themselves live in the rooms below).

- `fit_noise_extension`: the noise model extended by a file's measured noise level function and
  correlation kernel (`g2r_jax.sensor.noise.extension.extended_noise_model`).
- `attach_spectral`: a spectral model (sensitivities, lamp families) for `unprocess(...,
  colour="spectral")` (`g2r_jax.colour.spectral`).
"""

from __future__ import annotations

import numpy as np

from g2r_jax.profile.schema import SensorProfile, replace
from g2r_jax.sensor.noise.extension import DEFAULT_KNOTS, extended_noise_model


def fit_noise_extension(estimate, profile: SensorProfile, *, correlation=None, iso: float | None = None,
                        knots=DEFAULT_KNOTS, monotone: bool = False) -> SensorProfile:
    """The profile with its noise extended by a measured level function (and correlation kernel).

    **Arguments:** `estimate`: a `NoiseLevelEstimate` of one file (or of several files of one
    ISO pooled); `correlation`: a `NoiseCorrelationEstimate` (None: no kernel); `iso`: the
    files' ISO (default: the profile's, when it has one ISO row); `knots`, `monotone`: see
    `sensor.noise.extension.fit_level_function`.

    **Returns:** a `SensorProfile` whose `noise` is `extended_noise_model` of the profile's noise:
    the fitted function at the row of `iso`, the same shape scaled to the other ISO rows.
    """
    noise = extended_noise_model(estimate, profile.noise, profile.black_level, float(profile.white_level),
                                 correlation=correlation, iso=iso, knots=knots, monotone=monotone)
    return replace(profile, noise=noise)


def attach_spectral(profile: SensorProfile, sensitivities=None, *, source: str = "", chromaticities=None,
                    lamp_families=None, seed: int = 0) -> SensorProfile:
    """A copy of `profile` with a spectral model.

    **Arguments:**
    - `sensitivities`: (81, 3) on `colour.spectral.tables.WAVELENGTHS` (e.g.
      `io.sensitivities.read_sensitivities(path).values`); None: estimated from the profile's DNG
      matrices (`colour.spectral.estimate`).
    - `chromaticities`: measured illuminants (N, 2) as (r/g, b/g) that decide the lamp families;
      None: 500 draws from the profile's own illuminant distribution.
    - `lamp_families`: force the family names instead of choosing them.

    **Returns:** the profile with `spectral` set (its JSON gets the optional `spectral` object).
    """
    from g2r_jax.colour.spectral.estimate import estimate_sensitivities
    from g2r_jax.colour.spectral.model import spectral_model

    estimated = sensitivities is None
    if estimated:
        sensitivities, source = estimate_sensitivities(profile.colour)
    if lamp_families is None:
        lamp_families = _lamp_families(profile, sensitivities, chromaticities, seed)
    model = spectral_model(sensitivities, tuple(lamp_families), source=source, estimated=estimated,
                           dtype=profile.white_level.dtype)
    return replace(profile, spectral=model)


def _lamp_families(profile: SensorProfile, sensitivities, chromaticities, seed: int):
    """`choose_lamp_families` for the lights `chromaticities` (N, 2) (r/g, b/g), or for 500 draws
    of the profile's illuminant model when None; their CCT through the DNG neutral -> xy solve."""
    import jax

    from g2r_jax.colour import conversions as _colour
    from g2r_jax.colour import dng_model as _dng
    from g2r_jax.colour.spectral.illuminant_spectra import choose_lamp_families
    from g2r_jax.illuminants.distributions import sample_neutrals

    if chromaticities is None:
        neutrals = np.asarray(sample_neutrals(jax.random.PRNGKey(seed), profile.illuminants, 500))
        chromaticities = neutrals[:, [0, 2]] / neutrals[:, 1:2]
    chromaticities = np.asarray(chromaticities, np.float64)
    neutrals = np.stack([chromaticities[:, 0], np.ones(len(chromaticities)), chromaticities[:, 1]], -1)
    xy, _ = _dng.camera_neutrals_to_xy(np.asarray(neutrals, np.float32), profile.colour, throw=False)
    return choose_lamp_families(chromaticities, np.asarray(jax.jit(_colour.xy_to_CCT)(xy)), sensitivities)
