"""Measurement toolkit: the statistics that profile fitting, the audit and the downstream checks
all take from real files, written once.

- `robust`: robust spreads (`mad_sd`, `iqr_sd`, `trimmed_variance`; `robust_sd` with a
  resolution floor);
- `folds`: cross-validation folds that keep duplicate files together (`folds_of`,
  `duplicate_groups`, `pixel_hash`);
- `angular`: the illuminant angular error and its summary (`angular_error_degrees`,
  `error_summary`);
- `planes`: CFA site planes and the block-mean structure test;
- `dark_frames`: dark frames recognised and measured (`is_dark_frame`, `dark_frame_statistics`,
  `find_dark_frames`);
- `bursts`: static bursts told from unrelated files (`is_static_burst`, `find_bursts`,
  `scene_outliers`);
- `photon_transfer`: the temporal noise of a burst (`temporal_bins` + `fit_shot_read`,
  `temporal_nlf`, `regression_shot_read`).

Layer: above `io`, below `sensor` and everything else; it imports nothing of the package but `io`.
"""

from g2r_jax.measure.angular import angular_error_degrees, error_summary
from g2r_jax.measure.folds import duplicate_groups, folds_of, pixel_hash
from g2r_jax.measure.robust import iqr_sd, mad_sd, robust_sd, trimmed_variance

__all__ = ["angular_error_degrees", "duplicate_groups", "error_summary", "folds_of", "iqr_sd", "mad_sd",
           "pixel_hash", "robust_sd", "trimmed_variance"]
