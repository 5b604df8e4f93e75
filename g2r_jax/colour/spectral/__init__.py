"""The spectral sensor model (issue 11): camera sensitivities, illuminants as spectra, and sRGB
upsampled to reflectance; a sibling of the DNG-matrix colour model behind `unprocess`'s colour
stage (`unprocess(..., colour="spectral")`).

    from g2r_jax.profile.editing import attach_spectral
    profile = attach_spectral(g2r_jax.load_profile("s20fe_night"))   # estimated sensitivities
    mosaic, metadata = g2r_jax.unprocess(key, image, profile, colour="spectral")

Modules: `tables` (the 5 nm grid, CIE tables from colour-science), `model` (SpectralModel, JSON),
`illuminant_spectra` (neutral -> spectrum, lamp families), `upsampling` (Mallett-Yuksel,
Jakob-Hanika), `estimate` (sensitivities from DNG matrices), `stage` (the colour stage),
`accuracy` (the colour experiment of issue 11). A profile gets its spectral model from
`g2r_jax.profile.editing.attach_spectral` (assembling a profile is the profile room's job).
"""

from g2r_jax.colour.spectral.model import SpectralModel, spectral_model

__all__ = ["SpectralModel", "spectral_model"]
