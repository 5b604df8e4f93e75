"""SensorProfile: everything g2r_jax knows about one camera, as a pytree and as versioned JSON.

The numeric parts (matrices, levels, illuminant, exposure and noise models, sensor effects) are
arrays, so a profile can be a `jax.jit` argument; descriptive parts (names, provenance, the
camera's opcode lists) are static. On disk a profile is JSON with a schema name and version,
validated on load (never pickle).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from g2r_jax.runtime import x64 as _x64
from g2r_jax.runtime.host_arrays import device_array
from g2r_jax.illuminants import distributions as _illuminants
from g2r_jax import sensor as _sensor
from g2r_jax.colour.dng_model import DngColourModel
from g2r_jax.colour.spectral import model as _spectral_model
from g2r_jax import content as _content
from g2r_jax.profile import provenance as _provenance
from g2r_jax.profile.checks import ProfileError, check_document
from g2r_jax.profile.shipped import (  # re-exported: the shipped profiles' place and names
    SHIPPED_PROFILES_DIR, UnknownProfile, profile_path, shipped_profiles)

SCHEMA_NAME = "g2r_jax.sensor_profile"
SCHEMA_VERSION = 1

CFA_LETTERS = "RGB"
_EFFECT_DEFAULTS = {"black_pedestal": [0.0] * 4, "clip_level": 1.0, "channel_gain": [1.0] * 4,
                    "shading": [[0.0, 0.0]] * 4, "row_noise_std": 0.0, "column_noise_std": 0.0}


@dataclasses.dataclass(frozen=True)
class ProfileInfo:
    """Static, descriptive part of a profile (hashable, so it can live in a pytree's aux data)."""

    name: str = "unnamed"
    unique_camera_model: str = "g2r_jax camera"
    make: str = ""
    model: str = ""
    calibration_illuminants: tuple = (21,)   # EXIF codes, in the order of the colour model's matrices
    provenance: str = ""
    opcode_lists: tuple = ()   # (("OpcodeList3", "hex..."), ...) from the camera's DNGs
    provenance_parts: tuple = ()   # (("colour", text), ...) when given per part (`g2r_jax.profile.provenance`)


class SensorProfile(eqx.Module):
    """A fitted camera model. Build with `g2r_jax.fit` or `load_profile`."""

    cfa_pattern: Int[Array, "4"]           # colour (0=R, 1=G, 2=B) of tile positions, row-major
    black_level: Float[Array, "4"]         # DN per tile position
    white_level: Float[Array, ""]
    baseline_exposure: Float[Array, ""]
    colour: DngColourModel
    illuminants: _illuminants.IlluminantModel
    exposure: _sensor.ExposureModel
    noise: _sensor.NoiseModel
    effects: _sensor.SensorEffects
    info: ProfileInfo = eqx.field(static=True, default=ProfileInfo())
    spectral: Any = None                   # optional g2r_jax.colour.spectral.SpectralModel (sensitivities, lamps)
    content: Any = None                    # optional g2r_jax.content.ContentModel (the CG scenes' adaptation)

    @property
    def cfa_string(self) -> str:
        return "".join(CFA_LETTERS[int(c)] for c in np.asarray(self.cfa_pattern))


def parse_cfa(pattern) -> np.ndarray:
    """'RGGB' (or 4 colour indices) -> int array; must be a Bayer tile (one R, two G, one B)."""
    if isinstance(pattern, str):
        if len(pattern) != 4 or any(c not in CFA_LETTERS for c in pattern.upper()):
            raise ValueError(f"CFA pattern {pattern!r} is not four letters from R, G, B")
        indices = np.array([CFA_LETTERS.index(c) for c in pattern.upper()])
    else:
        indices = np.asarray(pattern, int).reshape(-1)
    if sorted(indices.tolist()) != [0, 1, 1, 2]:
        raise ValueError(f"CFA pattern {pattern!r} is not a Bayer 2x2 tile (one R, two G, one B)")
    return indices


def default_noise(dtype=np.float32) -> _sensor.NoiseModel:
    """A noiseless model (used when nothing is known about the sensor's noise)."""
    return _sensor.NoiseModel(iso=device_array([100.0], dtype), shot=device_array(np.zeros((1, 4)), dtype),
                              read=device_array(np.zeros((1, 4)), dtype), iso_range=device_array([100.0, 100.0], dtype))


# ------------------------------------------------------------------------------ JSON (de)serialise

def _list(a) -> Any:
    return np.asarray(a, np.float64).tolist()


def _noise_to_dict(noise: _sensor.NoiseModel) -> dict:
    """The `noise` object; the optional shape (`g2r_jax.sensor.noise.shape`) only when present."""
    document = {"iso": _list(noise.iso), "shot": _list(noise.shot), "read": _list(noise.read),
                "iso_range": _list(noise.iso_range)}
    if noise.level_variance is not None:
        document["level_function"] = {"knots": _list(noise.level_knots), "variance": _list(noise.level_variance)}
    if noise.correlation_kernel is not None:
        document["correlation_kernel"] = _list(noise.correlation_kernel)
    if noise.correlation_weight is not None:
        document["correlation_levels"] = {"knots": _list(noise.correlation_knots), "weight": _list(noise.correlation_weight)}
    if noise.read_excludes_quantisation:
        document["read_excludes_quantisation"] = True
    return document


def _noise_shape_from_dict(r, noise_doc, n_iso: int) -> dict:
    """Optional noise level function and correlation kernel of a `noise` object (validated)."""
    shape = {}
    level = r.get(noise_doc, "level_function", "noise", optional=True)
    if level is not None:
        knots = r.array(r.get(level, "knots", "noise.level_function"), "noise.level_function.knots", (None,))
        if len(knots) < 2 or np.any(np.diff(knots) <= 0):
            r.fail("noise.level_function.knots", "must be at least two strictly ascending signal values")
        variance = r.array(r.get(level, "variance", "noise.level_function"), "noise.level_function.variance",
                           (n_iso, 4, len(knots)))
        if np.any(variance < 0):
            r.fail("noise.level_function.variance", "must not be negative")
        shape.update(level_knots=knots, level_variance=variance)
    kernel = r.get(noise_doc, "correlation_kernel", "noise", optional=True)
    if kernel is not None:
        kernel = r.array(kernel, "noise.correlation_kernel", (4, 3, 3))
        if np.any(np.sum(kernel**2, axis=(1, 2)) <= 0):
            r.fail("noise.correlation_kernel", "a kernel of all zeros has no noise to correlate")
        shape["correlation_kernel"] = kernel
    levels = r.get(noise_doc, "correlation_levels", "noise", optional=True)
    if levels is not None:
        if kernel is None:
            r.fail("noise.correlation_levels", "needs a noise.correlation_kernel (the kernel's share by level)")
        knots = r.array(r.get(levels, "knots", "noise.correlation_levels"), "noise.correlation_levels.knots", (None,))
        if len(knots) < 2 or np.any(np.diff(knots) <= 0):
            r.fail("noise.correlation_levels.knots", "must be at least two strictly ascending signal values")
        weight = r.array(r.get(levels, "weight", "noise.correlation_levels"), "noise.correlation_levels.weight",
                         (4, len(knots)))
        if np.any((weight < 0) | (weight > 1)):
            r.fail("noise.correlation_levels.weight", "must lie in [0, 1] (the kernel's share)")
        shape.update(correlation_knots=knots, correlation_weight=weight)
    return shape


def profile_to_dict(profile: SensorProfile) -> dict:
    """The JSON document of a profile (schema `g2r_jax.sensor_profile`, version 1)."""
    colour, info = profile.colour, profile.info
    colour_tags = colour.dng_tags()   # each matrix set with its own illuminant
    illuminants = profile.illuminants
    cholesky = np.asarray(illuminants.cholesky, np.float64)
    effects = profile.effects
    return {
        "schema": SCHEMA_NAME,
        "version": SCHEMA_VERSION,
        "name": info.name,
        "camera": {"unique_camera_model": info.unique_camera_model, "make": info.make, "model": info.model},
        "provenance": _provenance.provenance_value(info),
        "cfa_pattern": profile.cfa_string,
        "black_level": _list(profile.black_level),
        "white_level": float(profile.white_level),
        "baseline_exposure": float(profile.baseline_exposure),
        "colour": {
            "calibration_illuminants": list(colour_tags["calibration_illuminants"]),
            "color_matrices": _list(colour_tags["color_matrices"]),
            "camera_calibrations": _list(colour_tags["camera_calibrations"]),
            "forward_matrices": _list(colour_tags["forward_matrices"]) if colour.has_forward_matrix else [],
            "analog_balance": _list(colour.analog_balance),
            **({"illuminant_data": [None if d is None else list(d) for d in colour_tags["illuminant_data"]]}
               if colour_tags["illuminant_data"] else {}),
        },
        "illuminants": {
            "kind": illuminants.kind,
            "weights": _list(illuminants.weights),
            "means": _list(illuminants.means),
            "covariances": _list(cholesky @ np.swapaxes(cholesky, -1, -2)),
            "hull": _list(illuminants.hull) if illuminants.use_hull else None,
        },
        "exposure": {"log2_mean": float(profile.exposure.log2_mean), "log2_std": float(profile.exposure.log2_std)},
        "noise": _noise_to_dict(profile.noise),
        "effects": {
            "black_pedestal": _list(effects.black_pedestal),
            "clip_level": float(effects.clip_level),
            "channel_gain": _list(effects.channel_gain),
            "shading": _list(effects.shading),
            "defects": [[int(r), int(c), float(v)] for r, c, v in
                        zip(np.asarray(effects.defect_rows), np.asarray(effects.defect_cols), np.asarray(effects.defect_values))],
            "row_noise_std": float(effects.row_noise_std),
            "column_noise_std": float(effects.column_noise_std),
        },
        "opcode_lists": {name: data for name, data in info.opcode_lists},
        **({} if profile.spectral is None else {"spectral": _spectral_model.spectral_to_dict(profile.spectral)}),
        **({} if profile.content is None else {"content": _content.content_to_dict(profile.content)}),
    }


class _Reader:
    """Typed access to a JSON document with errors that say where the problem is."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, where: str, problem: str):
        raise ProfileError(f"{self.source}: {where}: {problem}")

    def get(self, mapping, key, where, *, optional=False, default=None):
        if not isinstance(mapping, dict):
            self.fail(where, "expected an object")
        if key not in mapping or mapping[key] is None:
            if optional:
                return default
            self.fail(f"{where}.{key}", "missing")
        return mapping[key]

    def array(self, value, where, shape=None, *, positive=False):
        try:
            array = np.asarray(value, np.float64)
        except (TypeError, ValueError):
            self.fail(where, "expected numbers")
        if shape is not None and (array.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, array.shape))):
            self.fail(where, f"expected shape {tuple('N' if s is None else s for s in shape)}, got {array.shape}")
        if not np.all(np.isfinite(array)):
            self.fail(where, "contains NaN or infinity")
        if positive and np.any(array <= 0):
            self.fail(where, "must be positive")
        return array


def profile_from_dict(document: dict, source: str = "<profile>", dtype=np.float32) -> SensorProfile:
    """Validate a profile document and build the SensorProfile; raises ProfileError."""
    r = _Reader(source)
    dtype = jax.dtypes.canonicalize_dtype(dtype)  # float64 only inside an x64 context
    if not isinstance(document, dict) or document.get("schema") != SCHEMA_NAME:
        r.fail("schema", f"not a g2r_jax sensor profile (expected schema {SCHEMA_NAME!r})")
    version = document.get("version")
    if version != SCHEMA_VERSION:
        r.fail("version", f"unsupported version {version!r} (this g2r_jax reads version {SCHEMA_VERSION})")

    check_document(document, source)   # types and physical ranges (the same check before saving)
    as_j = lambda a: device_array(a, dtype)
    colour, cfa = _colour_from_dict(r, document, dtype)
    black = r.array(r.get(document, "black_level", "black_level"), "black_level", (4,))
    white = float(r.array(r.get(document, "white_level", "white_level"), "white_level", (), positive=True))
    if np.any(black >= white):
        r.fail("black_level", f"must be below white_level {white}")
    illuminant_model = _illuminants_from_dict(r, r.get(document, "illuminants", "illuminants"), dtype)
    exposure_doc = r.get(document, "exposure", "exposure", optional=True, default={"log2_mean": 0, "log2_std": 0})
    exposure = _sensor.ExposureModel(
        log2_mean=as_j(r.array(r.get(exposure_doc, "log2_mean", "exposure"), "exposure.log2_mean", ())),
        log2_std=as_j(r.array(r.get(exposure_doc, "log2_std", "exposure"), "exposure.log2_std", ())))
    noise_doc = r.get(document, "noise", "noise", optional=True)
    noise = default_noise(dtype) if noise_doc is None else _noise_from_dict(r, noise_doc, dtype)
    effects = _effects_from_dict(r, r.get(document, "effects", "effects", optional=True, default={}), dtype)
    info = _info_from_dict(r, document, source, colour)
    spectral_doc = r.get(document, "spectral", "spectral", optional=True)
    spectral = None if spectral_doc is None else _spectral_model.spectral_from_dict(spectral_doc, r.fail, dtype)
    content_doc = r.get(document, "content", "content", optional=True)
    content = None if content_doc is None else _content.content_from_dict(content_doc, r.fail)
    return SensorProfile(
        cfa_pattern=device_array(cfa, jnp.int32), black_level=as_j(black), white_level=as_j(white),
        baseline_exposure=as_j(float(document.get("baseline_exposure", 0.0))), colour=colour,
        illuminants=illuminant_model, exposure=exposure, noise=noise, effects=effects, info=info,
        spectral=spectral, content=content)


def _colour_from_dict(r, document: dict, dtype):
    """(DngColourModel, CFA pattern (4,)) of a profile document's `colour` and `cfa_pattern`."""
    colour_doc = r.get(document, "colour", "colour")
    codes = r.get(colour_doc, "calibration_illuminants", "colour")
    if not isinstance(codes, list) or len(codes) not in (1, 2, 3):
        r.fail("colour.calibration_illuminants", "expected a list of one to three EXIF LightSource codes")
    n = len(codes)
    illuminant_data = r.get(colour_doc, "illuminant_data", "colour", optional=True, default=[])
    if not isinstance(illuminant_data, list) or len(illuminant_data) not in (0, n):
        r.fail("colour.illuminant_data", f"expected a list of {n} entries (null or [x, y])")
    illuminant_data = [None if d is None else r.array(d, f"colour.illuminant_data[{k}]", (2,), positive=True)
                       for k, d in enumerate(illuminant_data)]
    matrices = r.array(r.get(colour_doc, "color_matrices", "colour"), "colour.color_matrices", (n, 3, 3))
    calibrations = r.get(colour_doc, "camera_calibrations", "colour", optional=True, default=[])
    calibrations = r.array(calibrations, "colour.camera_calibrations", (n, 3, 3)) if len(calibrations) else []
    forwards = r.get(colour_doc, "forward_matrices", "colour", optional=True, default=[])
    forwards = r.array(forwards, "colour.forward_matrices", (n, 3, 3)) if len(forwards) else []
    balance = r.array(r.get(colour_doc, "analog_balance", "colour", optional=True, default=[1, 1, 1]),
                      "colour.analog_balance", (3,), positive=True)
    try:
        colour = DngColourModel.from_tags(codes, matrices, calibrations, forwards, balance, dtype=dtype,
                                          illuminant_data=illuminant_data)
        cfa = parse_cfa(r.get(document, "cfa_pattern", "cfa_pattern"))
    except ValueError as error:
        r.fail("colour" if "CFA" not in str(error) else "cfa_pattern", str(error))
    return colour, cfa


def _illuminants_from_dict(r, ill: dict, dtype) -> _illuminants.IlluminantModel:
    kind = r.get(ill, "kind", "illuminants")
    if kind not in ("gaussian", "mixture", "locus", "prior", "kernel"):
        r.fail("illuminants.kind", f"unknown kind {kind!r}")
    weights = r.array(r.get(ill, "weights", "illuminants"), "illuminants.weights", (None,), positive=True)
    k = len(weights)
    means = r.array(r.get(ill, "means", "illuminants"), "illuminants.means", (k, 2), positive=True)
    covariances = r.array(r.get(ill, "covariances", "illuminants"), "illuminants.covariances", (k, 2, 2))
    if np.any(np.linalg.eigvalsh(0.5 * (covariances + np.swapaxes(covariances, -1, -2))) < -1e-12):
        r.fail("illuminants.covariances", "not positive semi-definite")
    hull = r.get(ill, "hull", "illuminants", optional=True)
    hull = None if hull is None else r.array(hull, "illuminants.hull", (None, 3))
    return _illuminants._model(weights, means, covariances, hull, kind, hull is not None, dtype)


def _noise_from_dict(r, noise_doc: dict, dtype) -> _sensor.NoiseModel:
    as_j = lambda a: device_array(a, dtype)
    iso = r.array(r.get(noise_doc, "iso", "noise"), "noise.iso", (None,), positive=True)
    if np.any(np.diff(iso) <= 0):
        r.fail("noise.iso", "must be strictly ascending")
    return _sensor.NoiseModel(
        iso=as_j(iso),
        shot=as_j(r.array(r.get(noise_doc, "shot", "noise"), "noise.shot", (len(iso), 4))),
        read=as_j(r.array(r.get(noise_doc, "read", "noise"), "noise.read", (len(iso), 4))),
        iso_range=as_j(r.array(r.get(noise_doc, "iso_range", "noise", optional=True,
                                     default=[iso.min(), iso.max()]), "noise.iso_range", (2,), positive=True)),
        read_excludes_quantisation=bool(noise_doc.get("read_excludes_quantisation", False)),
        **{k: as_j(v) for k, v in _noise_shape_from_dict(r, noise_doc, len(iso)).items()})


def _effects_from_dict(r, effects_doc: dict, dtype) -> _sensor.SensorEffects:
    as_j = lambda a: device_array(a, dtype)
    get_effect = lambda key, shape: r.array(r.get(effects_doc, key, "effects", optional=True, default=_EFFECT_DEFAULTS[key]),
                                            f"effects.{key}", shape)
    defects = r.get(effects_doc, "defects", "effects", optional=True, default=[])
    defects = r.array(defects, "effects.defects", (None, 3)) if len(defects) else np.zeros((0, 3))
    return _sensor.SensorEffects(
        black_pedestal=as_j(get_effect("black_pedestal", (4,))),
        clip_level=as_j(get_effect("clip_level", ())),
        channel_gain=as_j(get_effect("channel_gain", (4,))),
        shading=as_j(get_effect("shading", (4, 2))),
        defect_rows=device_array(defects[:, 0], jnp.int32),
        defect_cols=device_array(defects[:, 1], jnp.int32),
        defect_values=as_j(defects[:, 2]),
        row_noise_std=as_j(get_effect("row_noise_std", ())),
        column_noise_std=as_j(get_effect("column_noise_std", ())))


def _info_from_dict(r, document: dict, source: str, colour: DngColourModel) -> ProfileInfo:
    camera = r.get(document, "camera", "camera", optional=True, default={})
    opcode_lists = r.get(document, "opcode_lists", "opcode_lists", optional=True, default={})
    provenance, provenance_parts = _provenance.split_provenance(document.get("provenance"))
    return ProfileInfo(
        name=str(document.get("name", Path(source).stem)),
        unique_camera_model=str(camera.get("unique_camera_model", "g2r_jax camera")),
        make=str(camera.get("make", "")), model=str(camera.get("model", "")),
        calibration_illuminants=colour.calibration_illuminants,   # the model's order
        provenance=provenance, provenance_parts=provenance_parts,
        opcode_lists=tuple(sorted((str(k), str(v)) for k, v in opcode_lists.items())))


def load_profile(name_or_path, dtype=np.float32) -> SensorProfile:
    """Load a profile by path or by shipped name (see `shipped_profiles()`).

    **Returns:** a validated `SensorProfile`. Raises ProfileError naming the file and problem.
    """
    try:
        path = profile_path(name_or_path)   # a shipped name unless it is the path of a file
    except UnknownProfile as error:
        raise ProfileError(str(error)) from None
    try:
        document = json.loads(path.read_text())
    except FileNotFoundError:
        raise ProfileError(f"{path}: no such profile file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ProfileError(f"{path}: not valid JSON ({error})") from None
    except (OSError, RecursionError) as error:
        raise ProfileError(f"{path}: cannot read ({type(error).__name__})") from None
    try:
        return profile_from_dict(document, str(path), dtype)
    except ProfileError:
        raise
    except Exception as error:  # noqa: BLE001 - any other failure still names the file, in one line
        text = " ".join(str(error).split())[:160]
        raise ProfileError(f"{path}: malformed profile ({type(error).__name__}: {text})") from None


def save_profile(profile: SensorProfile, path) -> None:
    """Write a profile as JSON, atomically (temporary file, then rename), after the loader's own
    validation: a profile `load_profile` would refuse is never written (ProfileError instead)."""
    from g2r_jax.io.atomic import atomic_write_bytes

    document = profile_to_dict(profile)
    with _x64.enable_x64():
        profile_from_dict(document, str(path), np.float64)   # raises ProfileError naming the field
    text = json.dumps(document, indent=1, allow_nan=False)
    atomic_write_bytes(Path(path), (text + "\n").encode())


def replace(profile: SensorProfile, **changes) -> SensorProfile:
    """A copy of `profile` with some fields replaced (e.g. illuminants=..., effects=...)."""
    where = lambda p: [getattr(p, k) for k in changes]
    return eqx.tree_at(where, profile, list(changes.values()), is_leaf=lambda x: x is None)


def noise_from_table(iso, beta1_shot, beta2_read, black_level, white_level, dtype=np.float32) -> _sensor.NoiseModel:
    """NoiseModel from a calibration table in DN including the black level (var = b1 x + b2),
    like `s20fe_heteroscedastic_gaussian.csv`: converted to normalised units
    (shot = b1 / range, read = (b1 * black + b2) / range^2, range = white - black)."""
    iso = np.asarray(iso, np.float64)
    black = np.asarray(black_level, np.float64).reshape(1, 4)
    span = float(white_level) - black
    shot = np.asarray(beta1_shot, np.float64) / span
    read = (np.asarray(beta1_shot) * black + np.asarray(beta2_read)) / span**2
    return _sensor.NoiseModel(iso=device_array(iso, dtype), shot=device_array(shot, dtype),
                              read=device_array(read, dtype),
                              iso_range=device_array([iso.min(), iso.max()], dtype))
