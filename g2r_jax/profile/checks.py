"""Physical and type checks of a profile document: the one validation used by `load_profile`
(through `profile_from_dict`) and by `save_profile` before anything is written, so g2r-fit-profile
and g2r-diagnose never write a profile the loader would refuse.

`profile_from_dict` checks shapes and builds the model; this module checks, on the JSON document
itself, what a shape check cannot see: types (a list where an object is expected, None where a
number is), non-finite numbers, levels out of order or out of range, absurd or singular colour
matrices, negative noise, and sensor effects outside their physical range. Every problem is one
`ProfileError("<file>: <field>: <problem>")` line; values are never dumped.

Bounds (the same as for DNG tags where a field comes from one, `g2r_jax.io.tag_checks`):
levels 0 <= black < white <= 65535 with at least 32 DN between them; matrices within +-100 and
condition number <= 1e6; analog balance in [1e-3, 1e3]; baseline exposure within +-10 stops;
illuminant means (r/g, b/g) in [0.001, 1000]; exposure log2 mean within +-20, std in [0, 10]; noise
ISO in (0, 1e7], shot and read in [0, 1]; effects: black + pedestal within [0, white), clip level
in (0, 2], channel gains in (0, 10], shading gain 1 + a1 r^2 + a2 r^4 positive for r in [0, 1]
(entries within +-10), defects at non-negative integer positions with values in [0, 1], row and
column noise std in [0, 0.1] (a tenth of the range between black and white: at 1, half of a mid-grey
image's columns were clipped to 0 DN).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from g2r_jax.io.tag_checks import (
    _XYZ_D65,
    MAX_BASELINE_EV,
    MAX_CONDITION,
    MAX_GAIN,
    MAX_LEVEL,
    MAX_MATRIX_ENTRY,
    MIN_RANGE_DN)

MAX_BANDING_STD = 0.1   # row and column offsets' std, normalised

MIN_ISO, MAX_ISO = 1.0, 1e7   # noise.iso and noise.iso_range


class ProfileError(ValueError):
    """A profile that cannot be loaded; the message names the file and the problem."""


class _Check:
    def __init__(self, source: str):
        self.source = source

    def fail(self, field: str, problem: str):

        raise ProfileError(f"{self.source}: {field}: {problem}")

    def obj(self, value, field, *, optional=True) -> dict:
        if value is None:
            if optional:
                return {}
            self.fail(field, "missing")
        if not isinstance(value, dict):
            self.fail(field, f"expected an object, got {type(value).__name__}")
        return value

    def text(self, value, field):
        if value is not None and not isinstance(value, str):
            self.fail(field, f"expected text, got {type(value).__name__}")

    def numbers(self, value, field, *, low=-math.inf, high=math.inf, low_open=False, optional=False):
        """`value` as a float array (any nesting of lists of numbers), all within [low, high]."""
        if value is None:
            if optional:
                return None
            self.fail(field, "missing")
        if not _all_numbers(value):
            self.fail(field, "expected numbers")
        try:
            array = np.asarray(value, dtype=np.float64)
        except (ValueError, OverflowError):
            self.fail(field, "expected a regular array of numbers")
        if not np.all(np.isfinite(array)):
            self.fail(field, "contains NaN or infinity")
        if array.size and (np.min(array) < low or (low_open and np.min(array) <= low) or np.max(array) > high):
            bound = f"({low:g}" if low_open else f"[{low:g}"
            self.fail(field, f"values must lie in {bound}, {high:g}]")
        return array

    def matrices(self, value, field, *, kind):
        array = self.numbers(value, field, low=-MAX_MATRIX_ENTRY, high=MAX_MATRIX_ENTRY, optional=True)
        if array is None or array.size == 0:
            return
        if array.ndim != 3 or array.shape[1:] != (3, 3):
            return  # the shape check in profile_from_dict names the problem
        for k, m in enumerate(array):
            singular = np.linalg.svd(m, compute_uv=False)
            if singular[-1] <= 0 or singular[0] / singular[-1] > MAX_CONDITION:
                self.fail(f"{field}[{k}]", "singular or nearly singular matrix")
            if kind == "calibration" and np.any(np.diag(m) <= 0):
                self.fail(f"{field}[{k}]", "diagonal must be positive")
            if kind == "color" and np.any(m @ _XYZ_D65 <= 0):
                self.fail(f"{field}[{k}]", "gives a non-positive camera response to white light")
            if kind == "forward" and np.any(m @ np.ones(3) <= 0):
                self.fail(f"{field}[{k}]", "maps the camera's white to a non-positive XYZ")


def _all_numbers(value) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, numbers.Real):
        return True
    if isinstance(value, (list, tuple)):
        return all(_all_numbers(v) for v in value)
    return False


def check_document(document, source: str = "<profile>") -> None:
    """Raise ProfileError naming `source` and the field for the first implausible value."""
    c = _Check(source)
    if not isinstance(document, dict):
        c.fail("document", f"expected a JSON object, got {type(document).__name__}")
    _check_descriptions(c, document)
    black, white = _check_levels(c, document)
    _check_colour(c, c.obj(document.get("colour"), "colour", optional=False))
    _check_illuminants(c, c.obj(document.get("illuminants"), "illuminants", optional=False))
    exposure = c.obj(document.get("exposure"), "exposure")
    c.numbers(exposure.get("log2_mean"), "exposure.log2_mean", low=-20, high=20, optional=True)
    c.numbers(exposure.get("log2_std"), "exposure.log2_std", low=0, high=10, optional=True)
    noise = c.obj(document.get("noise"), "noise")
    if noise:
        _check_noise(c, noise, black, white)
    _check_effects(c, c.obj(document.get("effects"), "effects"), black, white)


def _check_descriptions(c: _Check, document: dict) -> None:
    """Names, provenance, camera and opcode lists: texts (the opcode lists hexadecimal bytes)."""
    for key in ("name", "cfa_pattern"):
        c.text(document.get(key), key)
    provenance = document.get("provenance")
    if isinstance(provenance, dict):   # one text per part (g2r_jax.profile.provenance)
        for key, value in provenance.items():
            if not isinstance(value, str):
                c.fail(f"provenance.{key}", f"expected text, got {type(value).__name__}")
    else:
        c.text(provenance, "provenance")
    camera = c.obj(document.get("camera"), "camera")
    for key, value in camera.items():
        c.text(value, f"camera.{key}")
    opcodes = c.obj(document.get("opcode_lists"), "opcode_lists")
    for key, value in opcodes.items():
        c.text(value, f"opcode_lists.{key}")
        try:
            bytes.fromhex(value)
        except ValueError:
            c.fail(f"opcode_lists.{key}", "not hexadecimal bytes")


def _check_levels(c: _Check, document: dict):
    """(black (array), white (float)) after checking their order and range, and the baseline exposure."""
    black = c.numbers(document.get("black_level"), "black_level", low=0.0)
    white = c.numbers(document.get("white_level"), "white_level", low=0.0, high=MAX_LEVEL, low_open=True)
    if white.ndim != 0:
        c.fail("white_level", "expected one number")
    white = float(white)
    if black.size and np.max(black) >= white:
        c.fail("black_level", f"{np.max(black):g} is not below white_level {white:g}")
    if black.size and white - np.max(black) < MIN_RANGE_DN:
        c.fail("white_level", f"{white:g} leaves only {white - np.max(black):g} DN above the black level")
    c.numbers(document.get("baseline_exposure"), "baseline_exposure", low=-MAX_BASELINE_EV, high=MAX_BASELINE_EV,
              optional=True)
    return black, white


def _check_colour(c: _Check, colour: dict) -> None:
    codes = colour.get("calibration_illuminants")
    if not isinstance(codes, list) or not codes or \
            any(isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 255 for v in codes):
        c.fail("colour.calibration_illuminants", "expected a list of EXIF LightSource codes (integers 0..255)")
    c.matrices(colour.get("color_matrices"), "colour.color_matrices", kind="color")
    c.matrices(colour.get("camera_calibrations"), "colour.camera_calibrations", kind="calibration")
    c.matrices(colour.get("forward_matrices"), "colour.forward_matrices", kind="forward")
    c.numbers(colour.get("analog_balance"), "colour.analog_balance", low=1 / MAX_GAIN, high=MAX_GAIN, optional=True)


def _check_illuminants(c: _Check, ill: dict) -> None:
    c.text(ill.get("kind"), "illuminants.kind")
    weights = c.numbers(ill.get("weights"), "illuminants.weights", low=0.0, high=1e6, low_open=True)
    if weights.size == 0:
        c.fail("illuminants.weights", "empty illuminant model")
    # as AsShotNeutral (g2r_jax.io.tag_checks): a mean of 1e-30 would draw non-positive neutrals
    c.numbers(ill.get("means"), "illuminants.means", low=1 / MAX_GAIN, high=MAX_GAIN)
    c.numbers(ill.get("covariances"), "illuminants.covariances", low=-1e3, high=1e3)
    c.numbers(ill.get("hull"), "illuminants.hull", low=-1e6, high=1e6, optional=True)


def _check_noise(c: _Check, noise: dict, black, white: float) -> None:
    # an ISO below 1 is no camera's setting, and 1e-320 is 0 in float32 (the simulation's log ISO: NaN)
    c.numbers(noise.get("iso"), "noise.iso", low=MIN_ISO, high=MAX_ISO)
    c.numbers(noise.get("shot"), "noise.shot", low=0, high=1)
    read = c.numbers(noise.get("read"), "noise.read", low=0, high=1)
    if read.size and black.size:   # a DNG's NoiseProfile O (read plus the 1/12 DN^2 rounding) must stay <= 1
        rounding = 1 / 12 / (white - float(np.max(black))) ** 2
        if float(np.max(read)) + rounding > 1:
            c.fail("noise.read", f"{float(np.max(read)):g} plus the rounding variance {rounding:.3g} exceeds 1 "
                                 "(normalised units)")
    iso_range = c.numbers(noise.get("iso_range"), "noise.iso_range", low=MIN_ISO, high=MAX_ISO, optional=True)
    if iso_range is not None and iso_range.size == 2 and iso_range.ravel()[0] > iso_range.ravel()[1]:
        c.fail("noise.iso_range", "expected [lowest, highest]")
    level = c.obj(noise.get("level_function"), "noise.level_function")
    if level:   # the noise shape of g2r_jax.sensor.noise.shape; shapes are checked by the loader
        c.numbers(level.get("knots"), "noise.level_function.knots", low=-1, high=2)
        c.numbers(level.get("variance"), "noise.level_function.variance", low=0, high=1)
    c.numbers(noise.get("correlation_kernel"), "noise.correlation_kernel", low=-100, high=100, optional=True)
    levels = c.obj(noise.get("correlation_levels"), "noise.correlation_levels")
    if levels:
        c.numbers(levels.get("knots"), "noise.correlation_levels.knots", low=-1, high=2)
        c.numbers(levels.get("weight"), "noise.correlation_levels.weight", low=0, high=1)
    if not isinstance(noise.get("read_excludes_quantisation", False), bool):
        c.fail("noise.read_excludes_quantisation", "expected true or false")


def _check_effects(c: _Check, effects: dict, black, white: float) -> None:
    pedestal = c.numbers(effects.get("black_pedestal"), "effects.black_pedestal", low=-MAX_LEVEL, high=MAX_LEVEL,
                         optional=True)
    if pedestal is not None and pedestal.size and black.size and pedestal.shape == black.shape:
        level = black + pedestal
        if np.min(level) < 0 or np.max(level) >= white:
            c.fail("effects.black_pedestal", f"black level plus pedestal must stay within [0, {white:g})")
    c.numbers(effects.get("clip_level"), "effects.clip_level", low=0, high=2, low_open=True, optional=True)
    c.numbers(effects.get("channel_gain"), "effects.channel_gain", low=0, high=10, low_open=True, optional=True)
    shading = c.numbers(effects.get("shading"), "effects.shading", low=-10, high=10, optional=True)
    if shading is not None and shading.ndim == 2 and shading.shape[1] == 2:
        radius2 = np.linspace(0.0, 1.0, 101)
        gains = 1 + shading[:, :1] * radius2 + shading[:, 1:] * radius2 ** 2
        if np.min(gains) <= 0:
            c.fail("effects.shading", "gives a non-positive gain inside the image")
    defects = effects.get("defects")
    if defects:
        table = c.numbers(defects, "effects.defects", low=-1e9, high=1e9)
        if table.ndim == 2 and table.shape[1] == 3:
            if np.any(table[:, :2] < 0) or np.any(table[:, :2] != np.round(table[:, :2])) or np.any(table[:, :2] > 1e6):
                c.fail("effects.defects", "positions must be non-negative integers")
            if np.any(table[:, 2] < 0) or np.any(table[:, 2] > 1):
                c.fail("effects.defects", "values must lie in [0, 1] (normalised)")
    for key in ("row_noise_std", "column_noise_std"):
        c.numbers(effects.get(key), f"effects.{key}", low=0, high=MAX_BANDING_STD, optional=True)
