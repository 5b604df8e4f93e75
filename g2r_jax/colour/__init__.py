"""The colour the sensor records: `conversions` (sRGB curves, CIE xy/CCT, Bradford; constants from
colour-science), `dng_model` (the DNG colour model: matrices interpolated by colour temperature),
`camera_rgb` (sRGB -> white-balanced camera RGB -> mosaic), `spectral` (the spectral model),
`charts` and `chart_fit` (measured colour charts and the colour refit), `spectrum_locus`
(which chromaticities a light can have)."""
