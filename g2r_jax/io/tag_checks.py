"""Plausibility checks of one DNG's tag values, applied where the tags are read.

`read_dng_info` parses what the DNG specification allows (Adobe, *Digital Negative (DNG)
Specification* 1.6, ch. 4); these checks refuse values that no camera writes and that would
otherwise reach solvers shared by a whole folder (the white-point fixed point, the matrix-pair
fit): non-finite numbers, levels out of order, singular or absurd matrices, non-positive neutrals.
A refused file raises `DngError(path, "Field: problem")`, one short line; the caller drops that
file and goes on with the others.

Bounds (documented here, tested in tests/test_tag_checks.py):
- levels: 0 <= BlackLevel < WhiteLevel <= 65535 (g2r_jax writes 16-bit DNGs), and at least
  `MIN_RANGE_DN` digital numbers between them (8-bit raw data is the smallest real range);
- ColorMatrix, CameraCalibration, ForwardMatrix: entries within +-`MAX_MATRIX_ENTRY`, condition
  number at most `MAX_CONDITION`; ColorMatrix must give a positive camera response to the D65 white
  (every colour channel of a real sensor responds to white light), CameraCalibration a positive
  diagonal, ForwardMatrix a positive XYZ for the camera's white (spec ch. 6: it maps white to D50);
- AnalogBalance within [1/`MAX_GAIN`, `MAX_GAIN`]; AsShotNeutral relative to green within
  [1/`MAX_NEUTRAL_RATIO`, `MAX_NEUTRAL_RATIO`] (real cameras' whites lie within about 0.1..3);
  AsShotWhiteXY inside the chromaticity triangle;
- BaselineExposure within +-`MAX_BASELINE_EV` stops; NoiseProfile S, O in [0, 1] (normalised units);
  ISO in [0, 1e7] (0: unknown); ExposureTime in [0, 1e5] s; CalibrationIlluminant codes 0..255.
"""

from __future__ import annotations

import numpy as np

from g2r_jax.io.dng_info import DngError, DngInfo

MIN_RANGE_DN = 32.0
MAX_LEVEL = 65535.0
MAX_MATRIX_ENTRY = 100.0
MAX_CONDITION = 1e6
MAX_GAIN = 1000.0
MAX_NEUTRAL_RATIO = 20.0
MAX_BASELINE_EV = 10.0
_XYZ_D65 = np.array([0.95047, 1.0, 1.08883])


def _fail(info: DngInfo, field: str, problem: str):
    raise DngError(info.path, f"{field}: {problem}")


def _finite(info, field, value) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(array)):
        _fail(info, field, "holds NaN or infinite values")
    return array


def check_matrix(info: DngInfo, field: str, matrix, *, kind: str) -> None:
    """A 3x3 colour matrix: finite, bounded, well conditioned, and sensible for its `kind`
    ('color', 'calibration' or 'forward')."""
    m = _finite(info, field, matrix)
    if m.shape != (3, 3):
        _fail(info, field, f"expected a 3x3 matrix, got shape {m.shape}")
    if np.max(np.abs(m)) > MAX_MATRIX_ENTRY:
        _fail(info, field, f"entry of magnitude {np.max(np.abs(m)):.3g} (colour matrices stay within "
                           f"+-{MAX_MATRIX_ENTRY:g})")
    singular = np.linalg.svd(m, compute_uv=False)
    if singular[-1] <= 0 or singular[0] / singular[-1] > MAX_CONDITION:
        _fail(info, field, "singular or nearly singular matrix")
    if kind == "color" and np.any(m @ _XYZ_D65 <= 0):
        _fail(info, field, "gives a non-positive camera response to white light")
    if kind == "calibration" and np.any(np.diag(m) <= 0):
        _fail(info, field, "diagonal must be positive")
    if kind == "forward" and np.any(m @ np.ones(3) <= 0):
        _fail(info, field, "maps the camera's white to a non-positive XYZ")


def check_levels(info: DngInfo) -> None:
    """BlackLevel (per tile position, after the deltas) and WhiteLevel in order and in range."""
    black = _finite(info, "BlackLevel", info.black_level).reshape(-1)
    white = float(_finite(info, "WhiteLevel", info.white_level))
    if black.size == 0:
        _fail(info, "BlackLevel", "no values")
    if np.min(black) < 0:
        _fail(info, "BlackLevel", f"negative black level {np.min(black):.6g} (with its deltas)")
    if not 0 < white <= MAX_LEVEL:
        _fail(info, "WhiteLevel", f"{white:.6g} is outside 1..{MAX_LEVEL:g}")
    if np.max(black) >= white:
        _fail(info, "BlackLevel", f"{np.max(black):.6g} is not below WhiteLevel {white:.6g}")
    if white - np.max(black) < MIN_RANGE_DN:
        _fail(info, "WhiteLevel", f"{white:.6g} leaves only {white - np.max(black):.6g} DN above the black "
                                  f"level (at least {MIN_RANGE_DN:g} expected)")
    table = getattr(info, "linearization_table", None)
    if table is not None and np.max(black) >= float(np.max(table)):
        _fail(info, "LinearizationTable", f"its largest value {float(np.max(table)):.6g} is not above the "
                                          f"black level {np.max(black):.6g}")


def check_dng_tags(info: DngInfo) -> DngInfo:
    """Raise `DngError(path, 'Field: problem')` for the first implausible tag value; return `info`."""
    check_levels(info)
    for k, code in enumerate(info.calibration_illuminants, start=1):
        if not 0 <= int(code) <= 255:
            _fail(info, f"CalibrationIlluminant{k}", f"code {int(code)} is not an EXIF LightSource (0..255)")
    for k, matrix in enumerate(info.color_matrices or (), start=1):
        check_matrix(info, f"ColorMatrix{k}", matrix, kind="color")
    for k, matrix in enumerate(info.camera_calibrations or (), start=1):
        check_matrix(info, f"CameraCalibration{k}", matrix, kind="calibration")
    for k, matrix in enumerate(info.forward_matrices or (), start=1):
        check_matrix(info, f"ForwardMatrix{k}", matrix, kind="forward")
    if info.analog_balance is not None:
        balance = _finite(info, "AnalogBalance", info.analog_balance)
        if np.any(balance < 1 / MAX_GAIN) or np.any(balance > MAX_GAIN):
            _fail(info, "AnalogBalance", f"values must lie in [{1 / MAX_GAIN:g}, {MAX_GAIN:g}]")
    if info.as_shot_neutral is not None:
        neutral = _finite(info, "AsShotNeutral", info.as_shot_neutral)
        if np.any(neutral <= 0):
            _fail(info, "AsShotNeutral", "values must be positive")
        relative = neutral / neutral[1]
        if np.any(relative < 1 / MAX_NEUTRAL_RATIO) or np.any(relative > MAX_NEUTRAL_RATIO) or \
                np.max(neutral) > MAX_GAIN:
            _fail(info, "AsShotNeutral", "values out of any plausible range")
    if info.as_shot_white_xy is not None:
        x, y = _finite(info, "AsShotWhiteXY", info.as_shot_white_xy)
        if not (0 < x < 1 and 0 < y < 1 and x + y < 1):
            _fail(info, "AsShotWhiteXY", f"({x:.4g}, {y:.4g}) is not a chromaticity")
    baseline = float(_finite(info, "BaselineExposure", info.baseline_exposure))
    if abs(baseline) > MAX_BASELINE_EV:
        _fail(info, "BaselineExposure", f"{baseline:.4g} stops is outside +-{MAX_BASELINE_EV:g}")
    if info.noise_profile is not None:
        noise = _finite(info, "NoiseProfile", info.noise_profile)
        if np.any(noise < 0) or np.any(noise > 1):
            _fail(info, "NoiseProfile", "scale and offset must lie in [0, 1] (normalised units)")
    if info.iso is not None:
        iso = float(_finite(info, "ISOSpeedRatings", info.iso))
        if not 0 <= iso <= 1e7:   # 0: unknown (fitting then assumes ISO 100)
            _fail(info, "ISOSpeedRatings", f"{iso:.6g} is not a plausible ISO")
    if info.exposure_time is not None:
        time = float(_finite(info, "ExposureTime", info.exposure_time))
        if not 0 <= time <= 1e5:
            _fail(info, "ExposureTime", f"{time:.6g} s is not a plausible exposure time")
    return info
