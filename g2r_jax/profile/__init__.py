"""The sensor profile: `schema` (the SensorProfile pytree, its JSON form, shipped profiles), `checks`
(types and physical ranges of a profile document), `fitting` (a profile from a folder of DNGs),
`editing` (a profile with a measured part added: noise extension, spectral model)."""
