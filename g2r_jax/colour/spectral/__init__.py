"""The spectral sensor model (issue 11): camera sensitivities, illuminants as spectra, and sRGB
upsampled to reflectance; a sibling of the DNG-matrix colour model behind `unprocess`'s colour
stage (`unprocess(..., colour="spectral")`).

    profile = g2r_jax.spectral.attach_spectral(g2r_jax.load_profile("s20fe_night"))  # estimated SSF
    mosaic, metadata = g2r_jax.unprocess(key, image, profile, colour="spectral")

Modules: `tables` (the 5 nm grid, CIE tables from colour-science), `model` (SpectralModel, JSON),
`illuminant_spectra` (neutral -> spectrum, lamp families), `upsampling` (Mallett-Yuksel,
Jakob-Hanika), `estimate` (sensitivities from DNG matrices), `stage` (the colour stage),
`accuracy` (the colour experiment of issue 11).
"""

from g2r_jax.colour.spectral.model import SpectralModel, spectral_model


def attach_spectral(profile, sensitivities=None, *, source: str = "", chromaticities=None,
                    lamp_families=None, seed: int = 0):
    """A copy of `profile` with a spectral model.

    **Arguments:**
    - `sensitivities`: (81, 3) on `tables.WAVELENGTHS` (e.g. `io.sensitivities.read_sensitivities(
      path).values`); None: estimated from the profile's DNG matrices (`estimate`).
    - `chromaticities`: measured illuminants (N, 2) as (r/g, b/g) that decide the lamp families;
      None: 500 draws from the profile's own illuminant distribution.
    - `lamp_families`: force the family names instead of choosing them.

    **Returns:** the profile with `spectral` set (its JSON gets the optional `spectral` object).
    """
    import jax
    import numpy as np

    from g2r_jax.colour import conversions as _colour
    from g2r_jax.colour import dng_model as _dng
    from g2r_jax.illuminants.distributions import sample_neutrals
    from g2r_jax.profile.schema import replace
    from g2r_jax.colour.spectral.estimate import estimate_sensitivities
    from g2r_jax.colour.spectral.illuminant_spectra import choose_lamp_families

    estimated = sensitivities is None
    if estimated:
        sensitivities, source = estimate_sensitivities(profile.colour)
    if lamp_families is None:
        if chromaticities is None:
            neutrals = np.asarray(sample_neutrals(jax.random.PRNGKey(seed), profile.illuminants, 500))
            chromaticities = neutrals[:, [0, 2]] / neutrals[:, 1:2]
        chromaticities = np.asarray(chromaticities, np.float64)
        neutrals = np.stack([chromaticities[:, 0], np.ones(len(chromaticities)), chromaticities[:, 1]], -1)
        xy, _ = _dng.camera_neutrals_to_xy(np.asarray(neutrals, np.float32), profile.colour, throw=False)
        lamp_families = choose_lamp_families(chromaticities, np.asarray(jax.jit(_colour.xy_to_CCT)(xy)), sensitivities)
    model = spectral_model(sensitivities, tuple(lamp_families), source=source, estimated=estimated,
                           dtype=profile.white_level.dtype)
    return replace(profile, spectral=model)


__all__ = ["SpectralModel", "attach_spectral", "spectral_model"]
