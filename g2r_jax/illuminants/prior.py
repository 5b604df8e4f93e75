"""A camera-independent prior over real scene illuminants, mapped into any camera.

The prior lives in (mired, Duv) (`g2r_jax.illuminants.mired_duv`), a plane of the light itself,
not of a sensor. It is a set of populations, each a Gaussian mixture fitted to measured scene
illuminants of several cameras (`g2r_jax.illuminants.prior_fit`; the shipped parameters and their
sources are in `data/illuminant_prior.json`):
- `daylight`: lights of the day sets at 4500 K and above (sun, sky, shade);
- `artificial`: lights of the day sets below 4500 K (incandescent, halogen, warm LED, mixed);
- `night`: night-time street and shop lights (sodium, mercury, LED).
A preset weighs them (`day`, the default for a profile from one DNG or a few: daylight and
artificial light 1:1; `night`; `day_night`). Every component gets an extra Duv spread
(`duv_spread`, 0.003: half the +-0.006 Duv tolerance of ANSI C78.377 lamps) for lights off the
fitted curve and for the error of a camera's colour matrices, which moves its lights' xy.

Into a camera: each component is split into sub-components along its major axis and each
sub-component mapped to the camera's (r/g, b/g) through the camera's DNG colour model, linearised
at its centre (mean -> camera chromaticity of that white, covariance -> J C J^T with J the
Jacobian of (mired, Duv) -> (r/g, b/g), by central differences). The result is an ordinary
`IlluminantModel` (kind 'prior'), restricted by rejection to the camera image of the prior's
support (`MIRED_RANGE`, |Duv| <= `DUV_LIMIT` and inside the spectrum locus: `duv_ceiling`) and to
positive r/g and b/g, so it is stored in and sampled from a profile like every other model.
"""

from __future__ import annotations

import functools
import json
import warnings
from dataclasses import dataclass
from importlib import resources
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.colour import dng_model as _dng
from g2r_jax.colour.spectrum_locus import locus_halfplanes
from g2r_jax.illuminants import distributions as _distributions
from g2r_jax.illuminants.mired_duv import DUV_SCALE, MIRED_RANGE, mired_duv_to_xy, mired_duv_to_xy_numpy
from g2r_jax.runtime.x64 import enable_x64

PRIOR_FILE = "illuminant_prior.json"
DEFAULT_PRESET = "day"
DUV_LIMIT = 0.03          # support of the prior in Duv (all real lights of the measured sets: |Duv| < 0.021)
SPLIT = 9                 # sub-components per component along its major axis
_MIN_CHROMATICITY = 1e-3  # r/g and b/g of a sampled neutral stay above this
MAX_UNREPRESENTABLE = 0.5   # share of the prior a camera's matrices may fail to map before they are refused


@dataclass(frozen=True)
class IlluminantPrior:
    """Populations of scene lights in (mired, Duv x 1000) and the presets that weigh them.

    `populations`: name -> dict(weights (K,), means (K, 2), covariances (K, 2, 2)) as fitted;
    `presets`: name -> {population: weight}; `duv_spread`: Duv standard deviation added to every
    component (Duv units, not x 1000); `source`: where the numbers come from.
    """

    populations: dict
    presets: dict
    duv_spread: float
    source: str = ""

    def mixture(self, preset: str = DEFAULT_PRESET):
        """(weights, means, covariances) of `preset` in (mired, Duv x 1000), `duv_spread` included."""
        if preset not in self.presets:
            raise ValueError(f"unknown illuminant prior preset {preset!r}; known: {', '.join(sorted(self.presets))}")
        weights, means, covariances = [], [], []
        for name, share in self.presets[preset].items():
            population = self.populations[name]
            weights.append(share * np.asarray(population["weights"], np.float64))
            means.append(np.asarray(population["means"], np.float64))
            covariances.append(np.asarray(population["covariances"], np.float64))
        weights = np.concatenate(weights)
        spread = np.diag([0.0, (self.duv_spread * DUV_SCALE) ** 2])
        return weights / weights.sum(), np.concatenate(means), np.concatenate(covariances) + spread


def prior_from_dict(document: dict, source: str = "<prior>") -> IlluminantPrior:
    """An `IlluminantPrior` from its JSON form (see `prior_fit.prior_to_dict`); ValueError naming
    `source` and the field when something is missing or malformed."""
    try:
        populations = {}
        for name, fields in document["populations"].items():
            weights = np.asarray(fields["weights"], np.float64)
            means = np.asarray(fields["means"], np.float64).reshape(len(weights), 2)
            covariances = np.asarray(fields["covariances"], np.float64).reshape(len(weights), 2, 2)
            if np.any(weights <= 0) or np.any(np.linalg.eigvalsh(covariances) <= 0):
                raise ValueError(f"population {name!r}: weights and covariances must be positive")
            populations[name] = dict(weights=weights, means=means, covariances=covariances)
        presets = {p: {k: float(v) for k, v in shares.items()} for p, shares in document["presets"].items()}
        for preset, shares in presets.items():
            unknown = set(shares) - set(populations)
            if unknown or not shares or min(shares.values()) <= 0:
                raise ValueError(f"preset {preset!r}: weights must be positive and name known populations "
                                 f"(unknown: {sorted(unknown)})")
        return IlluminantPrior(populations, presets, float(document["duv_spread"]), str(document.get("source", "")))
    except (KeyError, TypeError) as error:
        raise ValueError(f"{source}: illuminant prior with a missing or malformed field ({error})") from None
    except ValueError as error:
        raise ValueError(f"{source}: {error}") from None


def load_prior(path=None) -> IlluminantPrior:
    """The shipped prior (`g2r_jax/illuminants/data/illuminant_prior.json`) or the one at `path`."""
    if path is None:
        text = resources.files("g2r_jax.illuminants").joinpath("data", PRIOR_FILE).read_text()
        source = PRIOR_FILE
    else:
        text, source = open(path).read(), str(path)
    return prior_from_dict(json.loads(text), source)


def sample_mired_duv(prior: IlluminantPrior, n: int, preset: str = DEFAULT_PRESET, seed: int = 0) -> np.ndarray:
    """`n` draws (mired, Duv x 1000) from the prior itself (numpy; rejection to the support)."""
    weights, means, covariances = prior.mixture(preset)
    rng = np.random.default_rng(seed)
    cholesky = np.linalg.cholesky(covariances)
    kept = []
    while sum(len(k) for k in kept) < n:
        component = rng.choice(len(weights), 2 * n, p=weights)
        draws = means[component] + np.einsum("nij,nj->ni", cholesky[component], rng.standard_normal((2 * n, 2)))
        kept.append(draws[_in_support(draws)])
    return np.concatenate(kept)[:n]


@functools.lru_cache(maxsize=1)
def _duv_ceiling_table(count: int = 256):
    """(mired grid, largest Duv x 1000) of the support: |Duv| <= DUV_LIMIT and inside the hull of
    the spectrum locus (below ~2200 K the Planckian locus runs within 0.01 of it). Bisection on Duv."""
    mired = np.linspace(MIRED_RANGE[0], MIRED_RANGE[1], count)
    planes = locus_halfplanes()
    low, high = np.zeros(count), np.full(count, DUV_LIMIT * DUV_SCALE)
    for _ in range(40):
        middle = 0.5 * (low + high)
        xy = mired_duv_to_xy_numpy(np.stack([mired, middle], -1))
        inside = np.max(xy @ planes[:, :2].T + planes[:, 2], axis=1) <= 0
        low, high = np.where(inside, middle, low), np.where(inside, high, middle)
    return mired, low


def duv_ceiling(mired) -> np.ndarray:
    """Largest Duv x 1000 of the prior's support at `mired` (see `_duv_ceiling_table`)."""
    grid, ceiling = _duv_ceiling_table()
    return np.interp(mired, grid, ceiling)


def _in_support(points) -> np.ndarray:
    return ((points[:, 0] > MIRED_RANGE[0]) & (points[:, 0] < MIRED_RANGE[1])
            & (points[:, 1] > -DUV_LIMIT * DUV_SCALE) & (points[:, 1] < duv_ceiling(points[:, 0])))


def _split_along_major_axis(weights, means, covariances, count: int = SPLIT):
    """Each Gaussian as `count` narrower Gaussians along its major axis, same mean and covariance.

    Offsets c * t_i (t_i evenly spaced in [-2, 2]) weighted by the normal density at t_i; the
    scale c is chosen so the residual standard deviation along the axis equals the spacing
    (a smooth sum) and the mixture's variance along the axis is exactly the original one:
    c^2 (V + s^2) = 1 with V the weighted variance of t and s = 4 / (count - 1) the t-spacing.
    """
    t = np.linspace(-2.0, 2.0, count)
    shares = np.exp(-0.5 * t**2)
    shares /= shares.sum()
    spacing = 4.0 / (count - 1)
    scale = 1.0 / np.sqrt(np.sum(shares * t**2) + spacing**2)
    out_w, out_m, out_c = [], [], []
    for weight, mean, covariance in zip(weights, means, covariances):
        values, vectors = np.linalg.eigh(covariance)
        axis = vectors[:, -1] * np.sqrt(values[-1])
        narrowed = covariance - (1.0 - (scale * spacing) ** 2) * np.outer(axis, axis)
        for offset, share in zip(scale * t, shares):
            out_w.append(weight * share)
            out_m.append(mean + offset * axis)
            out_c.append(narrowed)
    return np.asarray(out_w), np.asarray(out_m), np.asarray(out_c)


@jax.jit
def _camera_chromaticities(points, colour_model):
    """(N, 2) (mired, Duv x 1000) -> (N, 2) camera (r/g, b/g) through the DNG model."""
    neutrals = jax.vmap(lambda xy: _dng.xy_to_camera_neutral(xy, colour_model))(mired_duv_to_xy(points))
    return neutrals[:, [0, 2]] / neutrals[:, 1:2]


def _support_outline(count: int = 64) -> np.ndarray:
    mired = np.linspace(MIRED_RANGE[0], MIRED_RANGE[1], count)
    return np.concatenate([np.stack([mired, np.full(count, -DUV_LIMIT * DUV_SCALE)], -1),
                           np.stack([mired, duv_ceiling(mired)], -1)])


class CameraPrior(NamedTuple):
    """The prior mapped into one camera (`camera_prior`) and the share of its weight (0-1) left out
    because the camera's colour matrices give those lights a non-positive or non-finite neutral."""

    model: _distributions.IlluminantModel
    left_out: float


def left_out_words(left_out: float, preset: str) -> str:
    """One clause counting the prior's lights a camera's matrices cannot carry ("" for none)."""
    if left_out <= 0:
        return ""
    return (f"{left_out:.1%} of the prior's {preset!r} lights (the warmest) left out: this camera's colour "
            "matrices give them a non-positive or non-finite neutral")


def camera_prior(colour_model, preset: str = DEFAULT_PRESET, prior: IlluminantPrior | None = None,
                 dtype=np.float32) -> CameraPrior:
    """The prior in one camera's (r/g, b/g), as `model_for_camera`, without a warning: the share
    of the prior left out comes back in the `CameraPrior` (ValueError above `MAX_UNREPRESENTABLE`)."""
    prior = load_prior() if prior is None else prior
    weights, means, covariances = _split_along_major_axis(*prior.mixture(preset))
    # one batch through the camera (one compilation): the centres, central differences for the
    # Jacobian (step 1e-3 in mired and in Duv x 1000; float64), and the support's outline
    step = 1e-3
    shifts = [np.array([step, 0.0]), np.array([-step, 0.0]), np.array([0.0, step]), np.array([0.0, -step])]
    outline_points = _support_outline()
    batch = np.concatenate([means] + [means + d for d in shifts] + [outline_points])
    with enable_x64():
        model64 = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float64) if eqx.is_array(a) else a,
                                         colour_model)
        mapped = np.asarray(_camera_chromaticities(jnp.asarray(batch, jnp.float64), model64))
    k = len(means)
    camera_means, plus_m, minus_m, plus_d, minus_d = (mapped[i * k:(i + 1) * k] for i in range(5))
    outline = mapped[5 * k:]
    jacobians = np.stack([(plus_m - minus_m) / (2 * step), (plus_d - minus_d) / (2 * step)], axis=-1)
    camera_covariances = np.einsum("kij,kjl,kml->kim", jacobians, covariances, jacobians)
    usable = (np.all(camera_means > _MIN_CHROMATICITY, axis=1) & np.all(np.isfinite(camera_means), axis=1)
              & np.all(np.isfinite(camera_covariances), axis=(1, 2)))
    lost = float(weights[~usable].sum())
    if lost > MAX_UNREPRESENTABLE:
        raise ValueError(f"the illuminant prior ({preset!r}) puts {lost:.1%} of its lights where this camera's "
                         "colour matrices give a non-positive or non-finite neutral: the matrices cannot carry it")
    weights, camera_means, camera_covariances = weights[usable], camera_means[usable], camera_covariances[usable]
    outline = outline[np.all(np.isfinite(outline), axis=1)]
    positive = np.array([[-1.0, 0.0, _MIN_CHROMATICITY], [0.0, -1.0, _MIN_CHROMATICITY]])
    hull = np.concatenate([_distributions.convex_hull_halfplanes(outline), positive])
    return CameraPrior(_distributions._model(weights, camera_means, camera_covariances, hull, "prior", True, dtype),
                       lost)


def model_for_camera(colour_model, preset: str = DEFAULT_PRESET, prior: IlluminantPrior | None = None,
                     dtype=np.float32) -> _distributions.IlluminantModel:
    """The prior in one camera's (r/g, b/g): an `IlluminantModel` of kind 'prior'.

    **Arguments:** `colour_model`: the camera's `DngColourModel`; `preset`: which weighting of
    the populations (`day`, `night`, `day_night`); `prior`: an `IlluminantPrior` (default: the
    shipped one); `dtype` of the returned model.

    **Returns:** the mixture mapped as the module docstring says. Sub-components whose white the
    camera's matrices turn into a non-positive or non-finite neutral (a one-matrix D65 model
    extrapolated to 1600 K can give negative blue) are left out with a warning that counts them,
    or, when they carry more than `MAX_UNREPRESENTABLE` of the weight, ValueError.
    """
    mapped = camera_prior(colour_model, preset, prior, dtype)
    if mapped.left_out > 0:
        warnings.warn(f"illuminant prior: {left_out_words(mapped.left_out, preset)}", stacklevel=2)
    return mapped.model


def sample_neutrals_for(key, colour_model, n: int, preset: str = DEFAULT_PRESET,
                        prior: IlluminantPrior | None = None):
    """`n` camera neutrals (n, 3), G = 1, drawn from the prior mapped into `colour_model`."""
    model = model_for_camera(colour_model, preset, prior, dtype=colour_model.color_matrix.dtype)
    return _distributions.sample_neutrals(key, model, n)
