"""The sensor: what happens to the light after the colour filters, in the order light meets it.

`exposure` (the global gain per image), `effects` (pedestal, early clipping, channel gains, radial
shading, defects, banding, levels and quantisation), `readout_stage` (`readout`: noise, banding,
levels and quantisation in one public function), `noise` (the noise model, its counter-based
stream, its shape, estimation from pixels, the fallback and the audit's extension), `shading`
(DNG lens-shading opcodes), `layout` (the CFA tile and its planes).

The names used across the package are re-exported here: `g2r_jax.sensor.NoiseModel`, ...
"""

from g2r_jax.sensor.effects import (
    SensorEffects,
    apply_optical_effects,
    apply_readout_effects,
    no_effects,
    shading_gain_mosaic,
    to_digital_numbers)
from g2r_jax.sensor.exposure import ExposureModel, fixed_exposure, sample_exposure_gain
from g2r_jax.sensor.layout import (
    from_planes,
    per_position,
    radial_distance_squared,
    radial_distance_squared_mosaic,
    to_planes)
from g2r_jax.sensor.noise.model import NoiseModel, add_noise, noise_level_at, noise_parameters, sample_iso
from g2r_jax.sensor.noise.stream import standard_normal, standard_normal_planes
from g2r_jax.sensor.readout_stage import ReadoutNoise, banding_effects, noise_at_iso, readout

__all__ = [
    "ExposureModel", "NoiseModel", "ReadoutNoise", "SensorEffects", "add_noise", "apply_optical_effects", "apply_readout_effects",
    "banding_effects", "fixed_exposure", "from_planes", "no_effects", "noise_at_iso", "noise_level_at", "noise_parameters", "per_position",
    "radial_distance_squared", "radial_distance_squared_mosaic", "readout", "sample_exposure_gain", "sample_iso",
    "shading_gain_mosaic", "standard_normal", "standard_normal_planes", "to_digital_numbers", "to_planes",
]
