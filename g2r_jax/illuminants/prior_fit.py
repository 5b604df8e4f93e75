"""Fitting the camera-independent illuminant prior (`g2r_jax.illuminants.prior`) to measured sets.

Each measured set is one camera's real scene illuminants (camera neutrals) with that camera's
DNG colour model. Every neutral goes to CIE xy through its own camera's model (the DNG fixed
point, `dng_model.camera_neutral_to_xy`) and on to (mired, Duv). The sets we have carry only a
D65 ColorMatrix, so their model is a one-matrix DNG model: the same matrix at every white, and
the same matrix maps the prior back into that camera for validation; the xy of a warm light is
then as wrong as that matrix is at 2500 K, an error the prior's Duv spread is meant to absorb.

The populations (see `prior`): day-set lights at 4500 K and above are `daylight`, below it
`artificial`; night sets are `night`. Within a population every camera has the same total
weight (a camera with 482 lights does not outvote one with 86: the scenes' mix is a property of
who took them, not of the world). Each population is a weighted Gaussian mixture fitted by EM
(Dempster, Laird & Rubin 1977), its size chosen by BIC (Schwarz 1978) with Kish's effective
sample size, a covariance floor of (10 mired, 0.0005 Duv) per component.

Regenerate the shipped file: `python -m g2r_jax.illuminants.prior_fit ../shared/data`.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from g2r_jax.colour import dng_model as _dng
from g2r_jax.illuminants.distributions import _gaussian_log_density
from g2r_jax.illuminants.mired_duv import xy_to_mired_duv
from g2r_jax.illuminants.prior import PRIOR_FILE, IlluminantPrior
from g2r_jax.io.atomic import atomic_write_bytes
from g2r_jax.runtime.x64 import enable_x64

DAYLIGHT_MIRED = 1e6 / 4500.0   # day-set lights bluer than 4500 K are 'daylight'
PRESETS = {"day": {"daylight": 0.5, "artificial": 0.5},
           "night": {"night": 1.0},
           "day_night": {"daylight": 0.4, "artificial": 0.4, "night": 0.2}}
DUV_SPREAD = 0.003              # half of ANSI C78.377's +-0.006 Duv lamp tolerance
COVARIANCE_FLOOR = np.diag([10.0**2, 0.5**2])
MAX_COMPONENTS = 4


@dataclass(frozen=True)
class MeasuredSet:
    """One camera's measured scene illuminants: `neutrals` (N, 3) camera RGB of the light,
    `colour_model` its DngColourModel (float64), `population` 'day' or 'night', `source` text."""

    name: str
    population: str
    neutrals: np.ndarray
    colour_model: object
    source: str


def _one_matrix_model(matrix):
    with enable_x64():
        return _dng.DngColourModel.from_tags([21], [np.asarray(matrix, np.float64).reshape(3, 3)], dtype=np.float64)


def measured_sets(data_root) -> list[MeasuredSet]:
    """The measured illuminant sets under `data_root` (the shared data folder): Gehler-Shi
    (Canon EOS-1D images 1-86, EOS 5D images 87-568) and the Samsung S20 FE night gray-card set
    (105 lights). Raises FileNotFoundError naming a missing file."""
    from scipy.io import loadmat

    root = Path(data_root)
    cameras = json.loads((root / "cameras/gehler_shi_cameras.json").read_text())
    mat = root / "illuminants/gehler_shi/real_illum_568.mat"
    rgb = np.asarray(loadmat(mat)["real_rgb"], np.float64)
    sets = []
    for name, rows in (("Canon EOS-1D", slice(0, 86)), ("Canon EOS 5D", slice(86, 568))):
        matrix = np.asarray(cameras[name]["color_matrix_d65"], np.float64) / cameras[name]["scale"]
        sets.append(MeasuredSet(name, "day", rgb[rows] / rgb[rows, 1:2], _one_matrix_model(matrix),
                                f"Gehler-Shi real_illum_568.mat images {cameras[name]['gehler_shi_images']}; "
                                "D65 ColorMatrix of LibRaw's table"))
    matrices = json.loads((root / "cameras/color_matrices.json").read_text())
    s20 = matrices["Samsung Galaxy S20 FE (main camera)"]["ColorMatrix_D65_tag21"]
    night = root / "illuminants/s20fe_night_graycard_105.csv"
    neutrals = np.loadtxt(night, delimiter=",", skiprows=1)
    sets.append(MeasuredSet("Samsung Galaxy S20 FE (night)", "night", neutrals / neutrals[:, 1:2],
                            _one_matrix_model(s20), "s20fe_night_graycard_105.csv; the phone's D65 ColorMatrix"))
    return sets


def set_mired_duv(measured: MeasuredSet) -> np.ndarray:
    """(N, 2) (mired, Duv x 1000) of a set's lights, through its own DNG model."""
    with enable_x64():
        xy, converged = _dng.camera_neutrals_to_xy(jnp.asarray(measured.neutrals, jnp.float64), measured.colour_model)
    if not np.all(np.asarray(converged)):
        raise ValueError(f"{measured.name}: the DNG white-point solve did not converge for some lights")
    return xy_to_mired_duv(np.asarray(xy))


def _weighted_em(points, weights, k, rng, iterations=500):
    """One EM run of a k-component mixture on weighted points (weights sum to 1)."""
    means = points[rng.choice(len(points), k, replace=False, p=weights)]
    covariances = np.stack([np.cov(points.T, aweights=weights) + COVARIANCE_FLOOR] * k)
    shares = np.full(k, 1.0 / k)
    previous = -np.inf
    for _ in range(iterations):
        log_p = np.stack([np.log(shares[j]) + _gaussian_log_density(points, means[j], covariances[j]) for j in range(k)], 1)
        total = np.logaddexp.reduce(log_p, axis=1)
        responsibility = np.exp(log_p - total[:, None]) * weights[:, None]
        counts = responsibility.sum(0) + 1e-300
        shares = counts / counts.sum()
        means = responsibility.T @ points / counts[:, None]
        for j in range(k):
            difference = points - means[j]
            covariances[j] = (responsibility[:, j, None] * difference).T @ difference / counts[j] + COVARIANCE_FLOOR
        log_likelihood = float(np.sum(weights * total))
        if abs(log_likelihood - previous) < 1e-10 * abs(log_likelihood):
            break
        previous = log_likelihood
    return shares, means, covariances, log_likelihood


def fit_population(points, weights, seed: int = 0, restarts: int = 8) -> dict:
    """Weighted Gaussian mixture of (mired, Duv x 1000) points, 1..MAX_COMPONENTS by BIC.

    The log-likelihood is the weighted mean times Kish's effective size n = (sum w)^2 / sum w^2.
    """
    points = np.asarray(points, np.float64)
    weights = np.asarray(weights, np.float64) / np.sum(weights)
    n_effective = 1.0 / np.sum(weights**2)
    rng = np.random.default_rng(seed)
    best = None
    for k in range(1, min(MAX_COMPONENTS, len(points) // 5) + 1):
        runs = [_weighted_em(points, weights, k, rng) for _ in range(restarts if k > 1 else 1)]
        shares, means, covariances, log_likelihood = max(runs, key=lambda run: run[3])
        bic = (6 * k - 1) * np.log(n_effective) - 2 * n_effective * log_likelihood
        if best is None or bic < best[0]:
            best = (bic, shares, means, covariances)
    _, shares, means, covariances = best
    return dict(weights=shares, means=means, covariances=covariances)


def population_points(sets, coordinates) -> dict:
    """Population name -> (points, weights): each camera's lights share weight 1 in a population."""
    grouped = {}
    for measured, points in zip(sets, coordinates):
        if measured.population == "night":
            parts = {"night": points}
        else:
            parts = {"daylight": points[points[:, 0] < DAYLIGHT_MIRED], "artificial": points[points[:, 0] >= DAYLIGHT_MIRED]}
        for name, part in parts.items():
            if len(part):
                grouped.setdefault(name, []).append(part)
    return {name: (np.concatenate(parts), np.concatenate([np.full(len(p), 1.0 / len(p)) for p in parts]))
            for name, parts in grouped.items()}


def fit_prior(sets, seed: int = 0) -> IlluminantPrior:
    """An `IlluminantPrior` from measured sets; presets whose populations are absent are dropped
    (e.g. no night set: no 'night' preset, and 'day_night' is not offered)."""
    coordinates = [set_mired_duv(s) for s in sets]
    populations = {name: fit_population(points, weights, seed)
                   for name, (points, weights) in population_points(sets, coordinates).items()}
    presets = {p: shares for p, shares in PRESETS.items() if set(shares) <= set(populations)}
    counts = ", ".join(f"{s.name}: {len(s.neutrals)} ({s.population}; {s.source})" for s in sets)
    return IlluminantPrior(populations, presets, DUV_SPREAD, source=f"fitted by g2r_jax.illuminants.prior_fit to {counts}")


def prior_to_dict(prior: IlluminantPrior) -> dict:
    """The JSON form read by `prior.prior_from_dict`."""
    rounded = lambda a: np.round(np.asarray(a, np.float64), 8).tolist()
    return {
        "about": "Camera-independent prior over scene illuminants in (mired, Duv x 1000) "
                 "(g2r_jax.illuminants.prior; coordinates: g2r_jax.illuminants.mired_duv).",
        "source": prior.source,
        "duv_spread": prior.duv_spread,
        "presets": prior.presets,
        "populations": {name: {key: rounded(value) for key, value in fields.items()}
                        for name, fields in prior.populations.items()},
    }


def write_prior(prior: IlluminantPrior, path) -> None:
    """Write the prior's JSON atomically (`g2r_jax.io.atomic`)."""
    atomic_write_bytes(Path(path), (json.dumps(prior_to_dict(prior), indent=1) + "\n").encode())


def main(argv=None) -> int:
    """`python -m g2r_jax.illuminants.prior_fit DATA_ROOT [OUTPUT]`: refit and write the prior."""
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print("usage: python -m g2r_jax.illuminants.prior_fit DATA_ROOT [OUTPUT]", file=sys.stderr)
        return 2
    output = Path(argv[1]) if len(argv) > 1 else Path(__file__).parent / "data" / PRIOR_FILE
    prior = fit_prior(measured_sets(argv[0]))
    write_prior(prior, output)
    print(f"wrote {output}: " + ", ".join(f"{n} {len(p['weights'])} component(s)" for n, p in prior.populations.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
