"""The DNG colour model, exactly as the DNG specification and the Adobe DNG SDK define it.

References: Adobe, *Digital Negative (DNG) Specification* 1.4-1.6, chapter 6 "Mapping Camera
Color Space to CIE XYZ Space" (matrix interpolation, "Translating White Balance xy Coordinates
to Camera Neutral Coordinates", "Translating Camera Neutral Coordinates to White Balance xy
Coordinates", "Camera to XYZ (D50) Transform"); Adobe DNG SDK 1.4 `dng_color_spec.cpp`.

    XYZtoCamera(xy)      = AB . CC(CCT) . CM(CCT)               (CC, CM interpolated in mired)
    neutral(xy)          = XYZtoCamera(xy) . XYZ(xy), normalised to G = 1
    xy(neutral)          = fixed point of xy <- xy(XYZtoCamera(xy)^-1 . neutral)
    CameraToXYZ_D50(xy)  = FM(CCT) . diag(inv(AB.CC) . neutral)^-1 . inv(AB.CC)     with ForwardMatrix
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
import optimistix as optx
from jaxtyping import Array, Float

from . import colour as _colour

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


def calibration_illuminant_cct(code: int) -> float:
    """CCT in kelvin of an EXIF LightSource code, as the Adobe DNG SDK assigns it.

    Raises ValueError for codes without a defined temperature (0 'unknown', 255 'other'
    without IlluminantData), since no interpolation is possible for them.
    """
    code = int(code)
    if code not in CALIBRATION_ILLUMINANT_CCT:
        raise ValueError(f"CalibrationIlluminant {code} has no defined colour temperature")
    return CALIBRATION_ILLUMINANT_CCT[code]


class DngColourModel(eqx.Module):
    """The colour tags of one camera, ordered so that index 0 has the lower CCT.

    A camera calibrated under one illuminant only holds the same matrices twice (the
    interpolation weight is then irrelevant), exactly as a DNG reader treats it.
    """

    calibration_cct: Float[Array, "2"]
    color_matrix: Float[Array, "2 3 3"]
    camera_calibration: Float[Array, "2 3 3"]
    forward_matrix: Float[Array, "2 3 3"]
    analog_balance: Float[Array, "3"]
    has_forward_matrix: bool = eqx.field(static=True, default=False)

    @classmethod
    def from_tags(cls, calibration_illuminants, color_matrices, camera_calibrations=(),
                  forward_matrices=(), analog_balance=None, dtype=np.float32) -> "DngColourModel":
        """Build the model from DNG tag values (one or two calibrated illuminants).

        **Arguments:** `calibration_illuminants`: EXIF LightSource codes, one per matrix;
        `color_matrices`: XYZ -> camera 3x3 matrices; optional `camera_calibrations`,
        `forward_matrices` (same length) and `analog_balance` (3,).

        **Returns:** a `DngColourModel`. Raises ValueError on missing or malformed tags.
        """
        dtype = jax.dtypes.canonicalize_dtype(dtype)  # float64 only inside an x64 context
        codes = [int(c) for c in calibration_illuminants]
        matrices = [np.asarray(m, np.float64).reshape(3, 3) for m in color_matrices]
        if not matrices:
            raise ValueError("no ColorMatrix tags")
        if len(codes) != len(matrices):
            raise ValueError(f"{len(matrices)} ColorMatrix tags but {len(codes)} CalibrationIlluminant tags")
        matrices, codes = matrices[:2], codes[:2]
        ccts = [calibration_illuminant_cct(c) for c in codes]
        identity = np.eye(3)
        calibrations = [np.asarray(m, np.float64).reshape(3, 3) for m in camera_calibrations][:2]
        calibrations = calibrations if len(calibrations) == len(matrices) else [identity] * len(matrices)
        forwards = [np.asarray(m, np.float64).reshape(3, 3) for m in forward_matrices][:2]
        has_forward = len(forwards) == len(matrices)
        forwards = forwards if has_forward else [identity] * len(matrices)
        order = np.argsort(ccts, kind="stable")
        if len(matrices) == 1:
            order = np.array([0, 0])
        balance = np.ones(3) if analog_balance is None else np.asarray(analog_balance, np.float64).reshape(3)
        pick = lambda ms: jnp.asarray(np.stack([ms[i] for i in order]), dtype)
        return cls(
            calibration_cct=jnp.asarray(np.asarray(ccts)[order], dtype),
            color_matrix=pick(matrices),
            camera_calibration=pick(calibrations),
            forward_matrix=pick(forwards),
            analog_balance=jnp.asarray(balance, dtype),
            has_forward_matrix=bool(has_forward),
        )


def interpolation_weight(cct, model: DngColourModel):
    """Weight of the lower-CCT matrix: linear in inverse CCT, clamped to [0, 1] (DNG spec 6)."""
    low, high = model.calibration_cct[0], model.calibration_cct[1]
    same = low == high
    span = jnp.where(same, 1.0, 1.0 / low - 1.0 / high)
    weight = (1.0 / cct - 1.0 / high) / span
    return jnp.where(same, 1.0, jnp.clip(weight, 0.0, 1.0))


def _interpolate(matrices, weight):
    return weight * matrices[0] + (1.0 - weight) * matrices[1]


@jax.jit
def matrix_XYZ_to_camera(xy, model: DngColourModel):
    """XYZtoCamera = AB . CC(CCT) . CM(CCT) at white balance xy (DNG spec, chapter 6)."""
    weight = interpolation_weight(_colour.xy_to_CCT(xy), model)
    color_matrix = _interpolate(model.color_matrix, weight)
    calibration = _interpolate(model.camera_calibration, weight)
    return (model.analog_balance[:, None] * calibration) @ color_matrix


@jax.jit
def xy_to_camera_neutral(xy, model: DngColourModel):
    """Camera neutral of white xy, normalised to G = 1 (DNG spec, "Translating White Balance
    xy Coordinates to Camera Neutral Coordinates")."""
    neutral = matrix_XYZ_to_camera(xy, model) @ _colour.xy_to_XYZ(xy)
    return neutral / neutral[1]


def _xy_at_weight(weight, neutral, model: DngColourModel):
    """White xy of `neutral` under the matrices interpolated with `weight`."""
    color_matrix = _interpolate(model.color_matrix, weight)
    calibration = _interpolate(model.camera_calibration, weight)
    XYZ = jnp.linalg.solve((model.analog_balance[:, None] * calibration) @ color_matrix, neutral)
    return _colour.XYZ_to_xy(XYZ)


def _weight_residual(weight, args):
    neutral, model = args
    return interpolation_weight(_colour.xy_to_CCT(_xy_at_weight(weight, neutral, model)), model) - weight


@functools.partial(jax.jit, static_argnames=("max_steps", "tolerance", "throw"))
def camera_neutral_to_xy(neutral, model: DngColourModel, *, max_steps: int = 200,
                         tolerance: float | None = None, throw: bool = True):
    """White-balance xy of a camera neutral: the DNG fixed point, solved with optimistix.

    DNG spec, "Translating Camera Neutral Coordinates to White Balance xy Coordinates":
    iterate xy <- XYZ_to_xy(XYZtoCamera(xy)^-1 . neutral) until it stops moving. XYZtoCamera
    depends on xy only through the interpolation weight w in [0, 1], so the fixed point is a
    root of g(w) = weight(CCT(xy(w))) - w, and g(-d) > 0 > g(1 + d): bisection (optimistix) always
    finds it, also where the specification's plain iteration cycles (the SDK then averages two
    iterates after 30 passes) or Newton's method overshoots.

    **Arguments:** `neutral` (3,) camera RGB of a neutral surface; `model`; `max_steps`;
    `tolerance` on w and on g (default: 100 ulp of the dtype; optimistix's bisection stops when
    both the bracket and |g| are below it, and |g| cannot get to a few ulp); `throw`: raise if it does not converge
    (set False inside sampling code and read the flag instead).

    **Returns:** `(xy, converged)`.
    """
    neutral = jnp.asarray(neutral)
    dtype = jnp.result_type(neutral, model.color_matrix)
    if tolerance is None:
        tolerance = float(100 * jnp.finfo(dtype).eps)
    neutral = neutral.astype(dtype)
    solver = optx.Bisection(rtol=tolerance, atol=tolerance)
    solution = optx.root_find(_weight_residual, solver, jnp.asarray(0.5, dtype), args=(neutral, model),
                              # a margin outside [0, 1] keeps g strictly positive/negative at the ends
                              # (g(0) = 0 when the white is beyond the upper calibration CCT)
                              options=dict(lower=jnp.asarray(-0.01, dtype), upper=jnp.asarray(1.01, dtype)),
                              max_steps=max_steps, throw=throw)
    converged = solution.result == optx.RESULTS.successful
    weight = solution.value
    xy = _xy_at_weight(weight, neutral, model)
    # a second, exact DNG step at the solved white (identical to xy at convergence)
    return _xy_at_weight(interpolation_weight(_colour.xy_to_CCT(xy), model), neutral, model), converged


@jax.jit
def matrix_camera_to_XYZ_D50(xy, model: DngColourModel):
    """CameraToXYZ_D50 at white xy (DNG spec, "Camera to XYZ (D50) Transform").

    With ForwardMatrix: FM . diag(ReferenceNeutral)^-1 . (AB.CC)^-1, where ReferenceNeutral =
    (AB.CC)^-1 . CameraNeutral(xy). Without: Bradford(xy -> D50) . XYZtoCamera(xy)^-1.
    """
    dtype = jnp.result_type(xy, model.color_matrix)
    if model.has_forward_matrix:
        weight = interpolation_weight(_colour.xy_to_CCT(xy), model)
        balance_calibration = model.analog_balance[:, None] * _interpolate(model.camera_calibration, weight)
        inverse_balance = jnp.linalg.inv(balance_calibration)
        reference_neutral = inverse_balance @ xy_to_camera_neutral(xy, model)
        forward = _interpolate(model.forward_matrix, weight)
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
