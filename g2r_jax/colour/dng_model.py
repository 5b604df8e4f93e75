"""The DNG colour model, exactly as the DNG specification and the Adobe DNG SDK define it.

References: Adobe, *Digital Negative (DNG) Specification* 1.4-1.6, chapter 6 "Mapping Camera
Color Space to CIE XYZ Space" (matrix interpolation, "Translating White Balance xy Coordinates
to Camera Neutral Coordinates", "Translating Camera Neutral Coordinates to White Balance xy
Coordinates", "Camera to XYZ (D50) Transform"); Adobe DNG SDK 1.4 `dng_color_spec.cpp`; for
DNG 1.6 three-illuminant cameras and IlluminantData, Adobe DNG SDK 1.6 `dng_xy_coord.cpp`
(`dng_illuminant_data`, `CalculateTripleIlluminantWeights`) and `dng_temperature.cpp`.

    XYZtoCamera(xy)      = AB . CC(xy) . CM(xy)     (CC, CM: sum_k w_k(xy) M_k, one w per illuminant)
    w(xy)                = mired interpolation at CCT(xy), two illuminants (clamped)
                         = SDK triple weights at (CCT, tint)(xy), three illuminants
    neutral(xy)          = XYZtoCamera(xy) . XYZ(xy), normalised to G = 1
    xy(neutral)          = fixed point of xy <- xy(XYZtoCamera(xy)^-1 . neutral)
    CameraToXYZ_D50(xy)  = FM(xy) . diag(inv(AB.CC) . neutral)^-1 . inv(AB.CC)     with ForwardMatrix
                         = Bradford(xy -> D50) . XYZtoCamera(xy)^-1                  without

Everything here is pure JAX on one colour (vmap for many); the fixed point is solved with
optimistix. `DngColourModel` is an equinox Module, so a pytree that can be a jit argument.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from g2r_jax.colour import conversions as _colour
from g2r_jax.runtime.host_arrays import device_array

# Adobe DNG SDK 1.4, dng_camera_profile.cpp, IlluminantToTemperature: CCT (K) of each EXIF
# LightSource code used as CalibrationIlluminant. (The SDK's own values, e.g. 2850 K for
# Standard Light A, which is what a DNG renderer uses.)
CALIBRATION_ILLUMINANT_CCT = {
    1: 5500.0,    # Daylight
    2: (3900.0 + 4500.0) / 2,   # Fluorescent
    3: 2850.0,    # Tungsten (incandescent)
    4: 5500.0,    # Flash
    9: 5500.0,    # Fine weather
    10: 6500.0,   # Cloudy weather
    11: 7500.0,   # Shade
    12: (5700.0 + 7100.0) / 2,  # Daylight fluorescent (D 5700 - 7100K)
    13: (4600.0 + 5400.0) / 2,  # Day white fluorescent (N 4600 - 5500K)
    14: (3900.0 + 4500.0) / 2,  # Cool white fluorescent (W 3800 - 4500K)
    15: (3200.0 + 3700.0) / 2,  # White fluorescent (WW 3250 - 3800K)
    16: (2600.0 + 3250.0) / 2,  # Warm white fluorescent (L 2600 - 3250K)
    17: 2850.0,   # Standard light A
    18: 5500.0,   # Standard light B
    19: 6500.0,   # Standard light C
    20: 5500.0,   # D55
    21: 6500.0,   # D65
    22: 7500.0,   # D75
    23: 5000.0,   # D50
    24: 3200.0,   # ISO studio tungsten
}

CALIBRATION_ILLUMINANT_NAMES = {
    1: "Daylight", 2: "Fluorescent", 3: "Tungsten", 4: "Flash", 9: "Fine weather",
    10: "Cloudy weather", 11: "Shade", 12: "Daylight fluorescent", 13: "Day white fluorescent",
    14: "Cool white fluorescent", 15: "White fluorescent", 16: "Warm white fluorescent",
    17: "Standard light A", 18: "Standard light B", 19: "Standard light C", 20: "D55",
    21: "D65", 22: "D75", 23: "D50", 24: "ISO studio tungsten",
}


OTHER_ILLUMINANT = 255   # EXIF LightSource 'other': its white is given by IlluminantData (DNG 1.6)

# Adobe DNG SDK 1.6, dng_xy_coord.cpp, dng_illuminant_data(light): the white xy the SDK assigns to
# each CalibrationIlluminant code (used by the three-illuminant weights); unknown codes get D50.
_XY_STANDARD_A, _XY_D50, _XY_D55 = (0.4476, 0.4074), (0.3457, 0.3585), (0.3324, 0.3474)
_XY_D65, _XY_D75 = (0.3127, 0.3290), (0.2990, 0.3149)
CALIBRATION_ILLUMINANT_XY = {
    3: _XY_STANDARD_A, 17: _XY_STANDARD_A,
    18: (0.348483, 0.351747), 19: (0.310061, 0.316150), 23: _XY_D50,
    1: _XY_D55, 4: _XY_D55, 9: _XY_D55, 20: _XY_D55,
    10: _XY_D65, 21: _XY_D65, 11: _XY_D75, 22: _XY_D75,
    12: (0.31310, 0.33727),   # daylight fluorescent: F1
    13: (0.34588, 0.35875),   # day white fluorescent: F8
    14: (0.37417, 0.37281),   # cool white fluorescent: F9
    2: (0.37208, 0.37529),    # fluorescent: F2
    15: (0.40910, 0.39430),   # white fluorescent: F3
    16: (0.44018, 0.40329),   # warm white fluorescent: F4
}
_ISO_STUDIO_TUNGSTEN = 24   # the SDK places it on the Robertson locus at 3200 K, tint 0


def calibration_illuminant_white_xy(code: int, illuminant_data=None) -> np.ndarray:
    """White xy of a CalibrationIlluminant as the Adobe DNG SDK 1.6 assigns it (dng_xy_coord.cpp,
    dng_illuminant_data): a fixed xy per EXIF LightSource code, the file's IlluminantData xy for
    255 'other', and D50 for codes without one (0 'unknown'). Raises ValueError for 255 without data.
    """
    code = int(code)
    if code == OTHER_ILLUMINANT:
        if illuminant_data is None:
            raise ValueError("CalibrationIlluminant 255 (other) needs IlluminantData giving its white")
        xy = np.asarray(illuminant_data, np.float64).reshape(-1)
        if xy.shape != (2,) or not np.all(np.isfinite(xy)) or np.any(xy <= 0) or xy.sum() >= 1:
            raise ValueError(f"IlluminantData white {tuple(xy)} is not a valid xy chromaticity")
        return xy
    if code == _ISO_STUDIO_TUNGSTEN:
        import colour
        return np.asarray(colour.UCS_uv_to_xy(colour.temperature.CCT_to_uv_Robertson1968(
            np.array([3200.0, 0.0]))), np.float64)
    return np.asarray(CALIBRATION_ILLUMINANT_XY.get(code, _XY_D50), np.float64)


def calibration_illuminant_cct(code: int, white_xy=None) -> float:
    """CCT in kelvin of an EXIF LightSource code, as the Adobe DNG SDK assigns it; for 255
    'other', the Robertson CCT of its IlluminantData `white_xy`.

    Raises ValueError for codes without a defined temperature (0 'unknown', 255 'other'
    without IlluminantData), since no interpolation is possible for them.
    """
    code = int(code)
    if code == OTHER_ILLUMINANT and white_xy is not None:
        import colour
        uv = colour.xy_to_UCS_uv(np.asarray(white_xy, np.float64))
        return float(colour.temperature.uv_to_CCT_Robertson1968(uv)[0])
    if code not in CALIBRATION_ILLUMINANT_CCT:
        raise ValueError(f"CalibrationIlluminant {code} has no defined colour temperature")
    return CALIBRATION_ILLUMINANT_CCT[code]


class DngColourModel(eqx.Module):
    """The colour tags of one camera: each ColorMatrix with its own CameraCalibration,
    ForwardMatrix and CalibrationIlluminant, ordered by ascending CCT.

    One calibrated illuminant: the matrices are held twice (the interpolation weight is then
    irrelevant), exactly as a DNG reader treats it. Two: interpolated in mired (DNG spec ch. 6).
    Three (DNG 1.6): weighted by distance to each illuminant's white in (tint, 1/CCT), as the
    Adobe DNG SDK 1.6 does (`triple_illuminant_weights`). `calibration_illuminants` holds the
    EXIF codes of the distinct tag sets in the same order as the arrays (static).
    """

    calibration_cct: Float[Array, "n"]
    color_matrix: Float[Array, "n 3 3"]
    camera_calibration: Float[Array, "n 3 3"]
    forward_matrix: Float[Array, "n 3 3"]
    analog_balance: Float[Array, "3"]
    illuminant_xy: Float[Array, "n 2"]
    has_forward_matrix: bool = eqx.field(static=True, default=False)
    calibration_illuminants: tuple = eqx.field(static=True, default=())

    @property
    def is_triple(self) -> bool:
        """True for a DNG 1.6 three-illuminant camera."""
        return self.color_matrix.shape[0] == 3

    @classmethod
    def from_tags(cls, calibration_illuminants, color_matrices, camera_calibrations=(),
                  forward_matrices=(), analog_balance=None, dtype=np.float32, *,
                  illuminant_data=()) -> "DngColourModel":
        """Build the model from DNG tag values (one, two or three calibrated illuminants), in any
        tag order: each matrix keeps its own illuminant.

        **Arguments:** `calibration_illuminants`: EXIF LightSource codes, one per matrix (a single
        matrix may have 0, unknown); `color_matrices`: XYZ -> camera 3x3 matrices; optional
        `camera_calibrations`, `forward_matrices` (same length), `analog_balance` (3,) and
        `illuminant_data`: per matrix, the white xy of a code-255 illuminant or None.

        **Returns:** a `DngColourModel`. Raises ValueError on missing or malformed tags.
        """
        dtype = jax.dtypes.canonicalize_dtype(dtype)  # float64 only inside an x64 context
        codes = [int(c) for c in calibration_illuminants]
        matrices = [np.asarray(m, np.float64).reshape(3, 3) for m in color_matrices]
        if not matrices:
            raise ValueError("no ColorMatrix tags")
        if len(codes) != len(matrices):
            raise ValueError(f"{len(matrices)} ColorMatrix tags but {len(codes)} CalibrationIlluminant tags")
        n = len(matrices)
        if n > 3:
            raise ValueError(f"{n} ColorMatrix tags; DNG defines at most three calibration illuminants")
        if n > 1:
            for k, code in enumerate(codes, start=1):
                if code == 0:
                    raise ValueError(f"{n} ColorMatrix tags but CalibrationIlluminant{k} is 0 (unknown): "
                                     "cannot interpolate between them")
        data = (list(illuminant_data) + [None] * n)[:n]
        whites = [calibration_illuminant_white_xy(c, d) for c, d in zip(codes, data)]
        ccts = []
        for code, white in zip(codes, whites):
            if n == 1 and code not in CALIBRATION_ILLUMINANT_CCT and code != OTHER_ILLUMINANT:
                ccts.append(5000.0)   # one matrix: its temperature is never used
            else:
                ccts.append(calibration_illuminant_cct(code, white))
        identity = np.eye(3)
        calibrations = [np.asarray(m, np.float64).reshape(3, 3) for m in camera_calibrations]
        calibrations = calibrations if len(calibrations) == n else [identity] * n
        forwards = [np.asarray(m, np.float64).reshape(3, 3) for m in forward_matrices]
        has_forward = len(forwards) == n
        forwards = forwards if has_forward else [identity] * n
        order = np.argsort(ccts, kind="stable")
        sorted_codes = tuple(codes[i] for i in order)
        if n == 1:
            order = np.array([0, 0])
        balance = np.ones(3) if analog_balance is None else np.asarray(analog_balance, np.float64).reshape(3)
        pick = lambda ms: device_array(np.stack([ms[i] for i in order]), dtype)
        return cls(
            calibration_cct=device_array(np.asarray(ccts)[order], dtype),
            color_matrix=pick(matrices),
            camera_calibration=pick(calibrations),
            forward_matrix=pick(forwards),
            analog_balance=device_array(balance, dtype),
            illuminant_xy=pick(whites),
            has_forward_matrix=bool(has_forward),
            calibration_illuminants=sorted_codes,
        )

    def dng_tags(self) -> dict:
        """The colour tags of this model as `DngInfo` fields, each set with its own illuminant:
        calibration_illuminants, color_matrices, camera_calibrations, forward_matrices and
        illuminant_data (xy of code-255 illuminants; empty when there are none)."""
        n = len(self.calibration_illuminants) or (3 if self.is_triple else 2)
        take = lambda a: tuple(np.asarray(a, np.float64)[:n])
        data = tuple(tuple(float(v) for v in np.asarray(self.illuminant_xy[k], np.float64))
                     if c == OTHER_ILLUMINANT else None for k, c in enumerate(self.calibration_illuminants))
        return dict(calibration_illuminants=tuple(self.calibration_illuminants),
                    color_matrices=take(self.color_matrix), camera_calibrations=take(self.camera_calibration),
                    forward_matrices=take(self.forward_matrix) if self.has_forward_matrix else (),
                    illuminant_data=data if any(d is not None for d in data) else ())


def interpolation_weight(cct, model: DngColourModel):
    """Weight of the lower-CCT matrix of a one- or two-illuminant model: linear in inverse CCT,
    clamped to [0, 1] (DNG spec 6)."""
    low, high = model.calibration_cct[0], model.calibration_cct[1]
    same = low == high
    span = jnp.where(same, 1.0, 1.0 / low - 1.0 / high)
    weight = (1.0 / cct - 1.0 / high) / span
    return jnp.where(same, 1.0, jnp.clip(weight, 0.0, 1.0))


def _triple_point(xy):
    """The SDK's scaled (tint / 200, min(1500 / CCT, 1)) coordinates of a white."""
    cct, tint = _colour.xy_to_CCT_tint(xy)
    return jnp.stack([tint / 200.0, jnp.minimum(1500.0 / cct, 1.0)], axis=-1)


def triple_illuminant_weights(xy, illuminant_xy):
    """Weights of three calibration illuminants at white xy (Adobe DNG SDK 1.6, dng_xy_coord.cpp,
    CalculateTripleIlluminantWeights): inverse squared distances (+1e-8) in the scaled
    (tint / 200, min(1500 / CCT, 1)) plane, normalised, smoothstepped, mapped so 0.02 -> 0 and
    clipped to [0, 1], renormalised."""
    distance = jnp.sum((_triple_point(illuminant_xy) - _triple_point(xy)) ** 2, axis=-1)
    weights = 1.0 / (distance + 1e-8)
    weights = weights / jnp.sum(weights)
    weights = weights * weights * (3.0 - 2.0 * weights)
    weights = jnp.clip((weights - 0.02) / 0.98, 0.0, 1.0)
    return weights / jnp.sum(weights)


def illuminant_weights(xy, model: DngColourModel):
    """Weight of each of the model's matrices at white xy (sums to 1)."""
    if model.is_triple:
        return triple_illuminant_weights(xy, model.illuminant_xy.astype(jnp.result_type(xy)))
    weight = interpolation_weight(_colour.xy_to_CCT(xy), model)
    return jnp.stack([weight, 1.0 - weight])


def _interpolate(matrices, weights):
    return jnp.tensordot(weights, matrices, axes=1)


@jax.jit
def matrix_XYZ_to_camera(xy, model: DngColourModel):
    """XYZtoCamera = AB . CC(xy) . CM(xy) at white balance xy (DNG spec, chapter 6)."""
    weights = illuminant_weights(xy, model)
    color_matrix = _interpolate(model.color_matrix, weights)
    calibration = _interpolate(model.camera_calibration, weights)
    return (model.analog_balance[:, None] * calibration) @ color_matrix


@jax.jit
def xy_to_camera_neutral(xy, model: DngColourModel):
    """Camera neutral of white xy, normalised to G = 1 (DNG spec, "Translating White Balance
    xy Coordinates to Camera Neutral Coordinates")."""
    neutral = matrix_XYZ_to_camera(xy, model) @ _colour.xy_to_XYZ(xy)
    return neutral / neutral[1]


def _xy_at_weights(weights, neutral, model: DngColourModel):
    """White xy of `neutral` under the matrices interpolated with `weights` (one per matrix)."""
    color_matrix = _interpolate(model.color_matrix, weights)
    calibration = _interpolate(model.camera_calibration, weights)
    XYZ = jnp.linalg.solve((model.analog_balance[:, None] * calibration) @ color_matrix, neutral)
    return _colour.XYZ_to_xy(XYZ)


def _xy_at_weight(weight, neutral, model: DngColourModel):
    return _xy_at_weights(jnp.stack([weight, 1.0 - weight]), neutral, model)


def _weight_residual(weight, args):
    neutral, model = args
    return interpolation_weight(_colour.xy_to_CCT(_xy_at_weight(weight, neutral, model)), model) - weight


def _triple_weights_from_pair(pair):
    return jnp.concatenate([pair, 1.0 - jnp.sum(pair, keepdims=True)])


def _triple_residual(pair, args):
    neutral, model = args
    xy = _xy_at_weights(_triple_weights_from_pair(pair), neutral, model)
    return illuminant_weights(xy, model)[:2] - pair


_SDK_PASSES = 30   # Adobe DNG SDK dng_color_spec::NeutralToXY: at most 30 passes from D50


def _camera_neutral_to_xy_triple(neutral, model, max_steps, tolerance, throw):
    """Three illuminants: the weights (w1, w2; w3 = 1 - w1 - w2) depend on xy through CCT and tint,
    so the fixed point is a root of the 2-D map g(w) = weights(xy(w)) - w on the simplex. g + w maps
    the simplex into itself continuously, so a root exists (Brouwer). Found by the specification's
    iteration from D50 (30 passes, as the SDK), then Newton's method (optimistix) from there; the
    result is accepted only when |g| <= tolerance, an a-posteriori check that it is the fixed point."""
    import optimistix as optx   # here, not at the top: a stored conversion program is run without tracing

    dtype = neutral.dtype
    step = lambda _, xy: _xy_at_weights(illuminant_weights(xy, model), neutral, model)
    xy_plain = jax.lax.fori_loop(0, _SDK_PASSES, step, jnp.asarray(_colour.XY_D50, dtype))
    start = illuminant_weights(xy_plain, model)[:2]
    solution = optx.root_find(_triple_residual, optx.Newton(rtol=tolerance, atol=tolerance), start,
                              args=(neutral, model), max_steps=max_steps, throw=False)
    newton_ok = (solution.result == optx.RESULTS.successful) & jnp.all(jnp.isfinite(solution.value))
    pair = jnp.where(newton_ok, solution.value, start)
    residual = jnp.max(jnp.abs(_triple_residual(pair, (neutral, model))))
    converged = residual <= 10 * tolerance
    xy = _xy_at_weights(_triple_weights_from_pair(pair), neutral, model)
    if throw:
        xy = eqx.error_if(xy, ~converged, "DNG neutral -> xy fixed point (three illuminants) did not converge")
    return _xy_at_weights(illuminant_weights(xy, model), neutral, model), converged


@functools.partial(jax.jit, static_argnames=("max_steps", "tolerance", "throw"))
def camera_neutral_to_xy(neutral, model: DngColourModel, *, max_steps: int = 200,
                         tolerance: float | None = None, throw: bool = True):
    """White-balance xy of a camera neutral: the DNG fixed point, solved with optimistix.

    DNG spec, "Translating Camera Neutral Coordinates to White Balance xy Coordinates":
    iterate xy <- XYZ_to_xy(XYZtoCamera(xy)^-1 . neutral) until it stops moving. With one or two
    illuminants XYZtoCamera depends on xy only through the interpolation weight w in [0, 1], so the
    fixed point is a root of g(w) = weight(CCT(xy(w))) - w, and g(-d) > 0 > g(1 + d): bisection
    (optimistix) always finds it, also where the specification's plain iteration cycles (the SDK
    then averages two iterates after 30 passes) or Newton's method overshoots. With three
    illuminants see `_camera_neutral_to_xy_triple` (2-D, Newton from the SDK's iterate, checked).

    **Arguments:** `neutral` (3,) camera RGB of a neutral surface; `model`; `max_steps`;
    `tolerance` on w and on g (default: 100 ulp of the dtype; optimistix's bisection stops when
    both the bracket and |g| are below it, and |g| cannot get to a few ulp); `throw`: raise if it does not converge
    (set False inside sampling code and read the flag instead).

    **Returns:** `(xy, converged)`.
    """
    import optimistix as optx   # here, not at the top: a stored conversion program is run without tracing

    neutral = jnp.asarray(neutral)
    dtype = jnp.result_type(neutral, model.color_matrix)
    if tolerance is None:
        tolerance = float(100 * jnp.finfo(dtype).eps)
    neutral = neutral.astype(dtype)
    if model.is_triple:
        return _camera_neutral_to_xy_triple(neutral, model, max_steps, tolerance, throw)
    # without `throw` nothing may stop the program (nor put a host callback in it, which keeps it
    # out of the persistent compilation cache): a root outside the bracket widens the bracket
    # (g is decreasing in w) instead of raising, and `converged` says how it went
    solver = optx.Bisection(rtol=tolerance, atol=tolerance, expand_if_necessary=not throw)
    solution = optx.root_find(_weight_residual, solver, jnp.asarray(0.5, dtype), args=(neutral, model),
                              # a margin outside [0, 1] keeps g strictly positive/negative at the ends
                              # (g(0) = 0 when the white is beyond the upper calibration CCT)
                              options=dict(lower=jnp.asarray(-0.01, dtype), upper=jnp.asarray(1.01, dtype)),
                              max_steps=max_steps, throw=throw)
    converged = solution.result == optx.RESULTS.successful
    weight = solution.value
    xy = _xy_at_weight(weight, neutral, model)
    # a second, exact DNG step at the solved white (identical to xy at convergence)
    return _xy_at_weights(illuminant_weights(xy, model), neutral, model), converged


@jax.jit
def matrix_camera_to_XYZ_D50(xy, model: DngColourModel):
    """CameraToXYZ_D50 at white xy (DNG spec, "Camera to XYZ (D50) Transform").

    With ForwardMatrix: FM . diag(ReferenceNeutral)^-1 . (AB.CC)^-1, where ReferenceNeutral =
    (AB.CC)^-1 . CameraNeutral(xy). Without: Bradford(xy -> D50) . XYZtoCamera(xy)^-1.
    """
    dtype = jnp.result_type(xy, model.color_matrix)
    if model.has_forward_matrix:
        weights = illuminant_weights(xy, model)
        balance_calibration = model.analog_balance[:, None] * _interpolate(model.camera_calibration, weights)
        inverse_balance = jnp.linalg.inv(balance_calibration)
        reference_neutral = inverse_balance @ xy_to_camera_neutral(xy, model)
        forward = _interpolate(model.forward_matrix, weights)
        return forward @ (inverse_balance / reference_neutral[:, None])
    adaptation = _colour.matrix_bradford(xy, jnp.asarray(_colour.XY_D50, dtype))
    return adaptation @ jnp.linalg.inv(matrix_XYZ_to_camera(xy, model))


@jax.jit
def matrix_XYZ_D65_to_camera(xy, model: DngColourModel):
    """The exact inverse of what a DNG renderer does from camera RGB to XYZ (D65-adapted).

    A renderer maps camera RGB to XYZ_D50 with CameraToXYZ_D50 and then to an sRGB (D65)
    output with Bradford(D50 -> D65); this returns the inverse of that product.
    """
    dtype = jnp.result_type(xy, model.color_matrix)
    d50_to_d65 = _colour.matrix_bradford(jnp.asarray(_colour.XY_D50, dtype), jnp.asarray(_colour.XY_D65, dtype))
    return jnp.linalg.inv(d50_to_d65 @ matrix_camera_to_XYZ_D50(xy, model))


def camera_neutrals_to_xy(neutrals, model: DngColourModel, **kwargs):
    """`camera_neutral_to_xy` vmapped over neutrals of shape (..., 3); returns (xy, converged)."""
    neutrals = jnp.asarray(neutrals)
    flat = neutrals.reshape(-1, 3)
    xy, converged = jax.vmap(lambda n: camera_neutral_to_xy(n, model, **kwargs))(flat)
    return xy.reshape(neutrals.shape[:-1] + (2,)), converged.reshape(neutrals.shape[:-1])
