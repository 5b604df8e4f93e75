"""Measurement toolkit: the statistics that profile fitting, the audit and the downstream checks
all take from real files, written once (robust spread, folds, angular error; dark frames, static
bursts and photon transfer as they move here).

Layer: above `io`, below `sensor` and everything else; it imports nothing of the package but `io`.
"""

from g2r_jax.measure.angular import angular_error_degrees, error_summary
from g2r_jax.measure.folds import duplicate_groups, folds_of, pixel_hash
from g2r_jax.measure.robust import iqr_sd, mad_sd, robust_sd, trimmed_variance

__all__ = ["angular_error_degrees", "duplicate_groups", "error_summary", "folds_of", "iqr_sd", "mad_sd",
           "pixel_hash", "robust_sd", "trimmed_variance"]
