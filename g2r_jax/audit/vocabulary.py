"""The cause vocabulary of the audit (ids used in REPORT.json) and what each one measures.

For every cause: the statistic that reveals it (a per-file vector, see `measures`), its
resolution (`floor`, added to the standard error) and the smallest difference worth reporting
(`tolerance`, in the statistic's units), so that a statistically certain but physically
irrelevant difference is not called a finding.
"""

from __future__ import annotations

CAUSES = (
    "illuminant_distribution", "exposure_distribution", "noise_model", "black_level", "white_level",
    "green_imbalance", "lens_shading", "defective_pixels", "banding",
)
UNEXPLAINED = "unexplained"

STATISTICS = {
    "illuminant_distribution": "energy distance and mean log density of the as-shot neutrals (r/g, b/g) against the profile's illuminant model",
    "exposure_distribution": "mean log2 signal of the image centre (well-exposed pixels), per file",
    "noise_model": "log ratio of the measured noise level function to the profile's at the file's ISO, dark (<5%) and bright bins, per CFA position",
    "black_level": "dark floor (0.5th percentile of 4x4 block means) minus the BlackLevel tag, fraction of range, per CFA position",
    "white_level": "saturation spike level above the dark floor, fraction of range, per CFA position",
    "green_imbalance": "median log(G2/G1) of 4x4 blocks of the two green CFA positions, over one dark floor common to both greens",
    "lens_shading": "log gain at the corners from the median radial gradient of log brightness per ring, per CFA position (one fitted fall-off per colour)",
    "defective_pixels": "number of pixels that are outliers against their same-colour neighbours in many files",
    "banding": "variance of row and column offsets from split-half covariance of row (column) medians",
    "noise_correlation": "log ratio of lag-2 to lag-1 difference variance in flat regions (1 for white noise)",
}

# statistic resolution (added to standard errors) and the smallest relevant difference
FLOOR = {
    "exposure_distribution": 0.01, "noise_model": 0.01, "black_level": 1e-4, "white_level": 3e-4,
    "green_imbalance": 5e-4, "lens_shading": 0.005, "banding": 1e-8, "noise_correlation": 0.005,
}
TOLERANCE = {
    "exposure_distribution": 0.1, "noise_model": 0.08, "black_level": 1e-3, "white_level": 3e-3,
    "green_imbalance": 5e-3, "lens_shading": 0.05, "banding": 1e-6, "noise_correlation": 0.05,
    "illuminant_distribution": 0.0, "defective_pixels": 0.0,
}
