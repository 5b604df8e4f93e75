"""Other cameras' measured lights carried into this camera: a population prior pooled across cameras.

A scene light is a property of the scene, not of the sensor, so what other cameras' lights look like
in their own raw space says what a new camera's lights will look like in its raw space (hierarchical
pooling: the new camera's lights as a draw from the population of all cameras' lights, Gelman et al.,
"Bayesian Data Analysis", 3rd ed., 2013, ch. 5). Each source camera's lights (its measured neutrals)
go to CIE xy through that camera's own DNG colour model (the DNG fixed point,
`dng_model.camera_neutrals_to_xy`) and are stored as (mired, Duv x 1000) (`mired_duv`); into a
camera they come through its colour model (`prior._camera_chromaticities`), and lights its
matrices cannot carry (a non-positive or non-finite neutral) are left out and counted. A source
whose D65 ColorMatrix is this camera's own (the same camera model) is left out too, wherever the
model is fitted: none of a camera's own lights informs its own prior (leave-one-camera-out).

The pooled model is the kernel model (`kernel.fit_kernel`, the NUS cameras' median bandwidths) of
the carried lights, every source camera with the same total weight (one camera's 260 lights do not
outvote another's 100: Kish, "Survey Sampling", 1965, on equal-weight strata), used in place of the
parametric prior as the Dirichlet-process base measure that the camera's own lights are blended
with (n0 = `kernel.PRIOR_PSEUDO_LIGHTS`). `exclude` names source cameras to leave out: the camera
under test in a leave-one-camera-out measurement, so that none of its lights informs its own prior.

Sources (`data/pooled_lights.json`, rebuilt by `python -m g2r_jax.illuminants.pooled
../shared/data`): the nine NUS cameras' measured lights (../shared/data/estimation/nus, Adobe's
A/D65 ColorMatrix pair of each, ../shared/data/cameras/color_matrices.json) and the Gehler-Shi Canon
EOS-1D and 5D lights (their D65 ColorMatrix of LibRaw's table). The NUS cameras photographed many of
the same scenes, so a left-out NUS camera's scenes may still be lit alike in the others' lights.
"""

from __future__ import annotations

import json
import sys
from importlib import resources
from pathlib import Path
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.colour import dng_model as _dng
from g2r_jax.illuminants import distributions as _distributions
from g2r_jax.illuminants import kernel as _kernel
from g2r_jax.illuminants.mired_duv import xy_to_mired_duv
from g2r_jax.runtime.x64 import enable_x64

POOLED_FILE = "pooled_lights.json"
_MIN_CHROMATICITY = 1e-3
D65 = 21                 # EXIF LightSource code of the calibration illuminant whose matrix names a camera
SAME_MATRIX = 1e-3       # largest difference of two unit-norm D65 ColorMatrices of one camera model


class CarriedLights(NamedTuple):
    """Pooled lights in one camera: (M, 2) (r/g, b/g), (M,) weights summing to 1, the share of the
    pool's weight left out (the camera's matrices cannot carry it) and the source cameras used."""

    chromaticities: np.ndarray
    weights: np.ndarray
    left_out: float
    sources: tuple


def load_pooled(path=None) -> dict:
    """{source camera: (N, 2) (mired, Duv x 1000)} of the shipped pool or the JSON at `path`;
    ValueError naming the file for a malformed one. Each source's D65 ColorMatrix is in
    `load_pool_matrices`."""
    if path is None:
        text, source = resources.files("g2r_jax.illuminants").joinpath("data", POOLED_FILE).read_text(), POOLED_FILE
    else:
        text, source = Path(path).read_text(), str(path)
    try:
        pool = {name: np.asarray(points, np.float64).reshape(-1, 2)
                for name, points in json.loads(text)["cameras"].items()}
    except (KeyError, TypeError, ValueError) as error:
        raise ValueError(f"{source}: pooled lights with a missing or malformed field ({error})") from None
    if not pool or not all(len(p) and np.all(np.isfinite(p)) for p in pool.values()):
        raise ValueError(f"{source}: pooled lights need at least one camera, each with finite lights")
    return pool


def load_pool_matrices(path=None) -> dict:
    """{source camera: (3, 3) D65 ColorMatrix} of the shipped pool or the JSON at `path`."""
    if path is None:
        text = resources.files("g2r_jax.illuminants").joinpath("data", POOLED_FILE).read_text()
    else:
        text = Path(path).read_text()
    return {name: np.asarray(m, np.float64).reshape(3, 3) for name, m in json.loads(text).get("d65_matrices", {}).items()}


def same_camera_sources(colour_model, matrices) -> tuple:
    """The sources whose D65 ColorMatrix (unit norm) is this camera's D65 one: its own lights."""
    codes = list(colour_model.calibration_illuminants)
    if D65 not in codes:
        return ()
    own = np.asarray(colour_model.color_matrix, np.float64)[codes.index(D65)]
    own = own / np.linalg.norm(own)
    return tuple(name for name, m in matrices.items() if np.max(np.abs(m / np.linalg.norm(m) - own)) < SAME_MATRIX)


def carried_lights(colour_model, exclude=(), pool=None, matrices=None) -> CarriedLights:
    """The pool's lights (all source cameras but `exclude` and this camera's own, by its D65
    matrix: `same_camera_sources`) in this camera's (r/g, b/g)."""
    from g2r_jax.illuminants.prior import _camera_chromaticities

    if pool is None:
        pool, matrices = load_pooled(), load_pool_matrices() if matrices is None else matrices
    left_out = set(exclude) | set(same_camera_sources(colour_model, matrices or {}))
    sources = tuple(name for name in sorted(pool) if name not in left_out)
    if not sources:
        raise ValueError(f"no pooled lights left after leaving out {sorted(exclude)}")
    points = np.concatenate([pool[name] for name in sources])
    weights = np.concatenate([np.full(len(pool[name]), 1.0 / (len(sources) * len(pool[name]))) for name in sources])
    with enable_x64():
        colour64 = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float64) if eqx.is_array(a) else a,
                                          colour_model)
        mapped = np.asarray(_camera_chromaticities(jnp.asarray(points, jnp.float64), colour64))
    usable = np.all(np.isfinite(mapped), axis=1) & np.all(mapped > _MIN_CHROMATICITY, axis=1)
    if not np.any(usable):
        raise ValueError("this camera's colour matrices give every pooled light a non-positive neutral")
    kept = weights[usable]
    return CarriedLights(mapped[usable], kept / kept.sum(), float(weights[~usable].sum()), sources)


class PooledBase(NamedTuple):
    """The base measure of `fit_pooled`: the kernel model of the carried lights (float64), the
    words that describe it and the source cameras whose lights it holds."""

    model: object
    words: str
    sources: tuple


def pooled_base(colour_model, tangents_of, exclude=(), pool=None) -> PooledBase:
    """The kernel model of the pooled lights carried into this camera (float64), every source
    camera with the same total weight; the base measure of `fit_pooled` (a `PooledBase`)."""
    carried = carried_lights(colour_model, exclude, pool)
    base = _kernel.fit_kernel(carried.chromaticities, tangents_of(carried.chromaticities),
                              bandwidths=_kernel.DEFAULT_BANDWIDTHS, weights=carried.weights, dtype=np.float64)
    left = (f"; {carried.left_out:.1%} of them left out: this camera's colour matrices give them a non-positive "
            "or non-finite neutral" if carried.left_out > 0 else "")
    return PooledBase(base, f"{len(carried.chromaticities)} lights of {len(carried.sources)} measured cameras "
                            f"carried through this camera's colour matrices{left}", carried.sources)


def fit_pooled(points, colour_model, tangents_of, exclude=(), pool=None, dtype=np.float32, base=None):
    """(model, words): the kernel model of this camera's `points` (N, 2), N >= 0, blended with the
    pooled lights' kernel model as its base measure (module docstring). `tangents_of(points)`
    gives the camera's locus tangents at points (`choice.camera_locus_tangents`); `base`: a
    `pooled_base` result to reuse (it depends only on the camera and `exclude`)."""
    base, pooled_words, _ = pooled_base(colour_model, tangents_of, exclude, pool) if base is None else base
    points = np.asarray(points, np.float64).reshape(-1, 2)
    if len(points) == 0:
        return _distributions._model(np.asarray(base.weights, np.float64), np.asarray(base.means, np.float64),
                                     _covariances(base), np.asarray(base.hull, np.float64), "kernel", True,
                                     dtype), f"the kernel density of {pooled_words}"
    along, across = _kernel.choose_bandwidths(points, tangents_of(points))
    model = _kernel.fit_kernel(points, tangents_of(points), prior=base, bandwidths=(along, across), dtype=dtype)
    share = _kernel.prior_share(len(points))
    return model, (f"kernel density of the {len(points)} measured light(s) (bandwidths {along:.3g} along, "
                   f"{across:.3g} across) with {share:.0%} of the kernel density of {pooled_words}")


def _covariances(model) -> np.ndarray:
    cholesky = np.asarray(model.cholesky, np.float64)
    return cholesky @ np.swapaxes(cholesky, -1, -2)


def _nus_sets(root: Path):
    matrices = json.loads((root / "cameras" / "color_matrices.json").read_text())
    for npz in sorted((root / "estimation" / "nus").glob("*.npz")):
        tags = matrices[npz.stem]
        with enable_x64():
            colour = _dng.DngColourModel.from_tags(
                (17, 21), (np.reshape(tags["ColorMatrix_StandardLightA_tag17"], (3, 3)),
                           np.reshape(tags["ColorMatrix_D65_tag21"], (3, 3))), dtype=np.float64)
        yield npz.stem, np.asarray(np.load(npz)["illuminants"], np.float64), colour


def build_pool(data_root) -> dict:
    """The pool's JSON document from the shared data folder (module docstring: the sources)."""
    from g2r_jax.illuminants.prior_fit import measured_sets

    root = Path(data_root)
    sets = list(_nus_sets(root))
    sets += [(m.name, m.neutrals, m.colour_model) for m in measured_sets(root) if m.population == "day"]
    cameras, about, matrices = {}, {}, {}
    for name, neutrals, colour in sets:
        codes = list(colour.calibration_illuminants)
        matrices[name] = np.round(np.asarray(colour.color_matrix, np.float64)[codes.index(D65)], 6).reshape(-1).tolist()
        neutrals = neutrals / neutrals[:, 1:2]
        with enable_x64():
            xy, converged = _dng.camera_neutrals_to_xy(jnp.asarray(neutrals, jnp.float64), colour)
        keep = np.asarray(converged) & np.all(np.isfinite(np.asarray(xy)), axis=1)
        cameras[name] = np.round(xy_to_mired_duv(np.asarray(xy)[keep]), 4).tolist()
        about[name] = f"{int(keep.sum())} of {len(neutrals)} lights"
    return {"about": "measured scene lights of several cameras as (mired, Duv x 1000), each through its own "
                     "camera's DNG colour model (g2r_jax.illuminants.pooled)",
            "source": "; ".join(f"{k}: {v}" for k, v in about.items()) + " (NUS: ../shared/data/estimation/nus "
                      "with Adobe's A/D65 ColorMatrix pair; Canon EOS-1D/5D: Gehler-Shi real_illum_568.mat "
                      "with the D65 ColorMatrix of LibRaw's table)",
            "cameras": cameras, "d65_matrices": matrices}


def main(argv=None) -> int:
    from g2r_jax.io.atomic import atomic_write_bytes

    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m g2r_jax.illuminants.pooled DATA_ROOT", file=sys.stderr)
        return 2
    document = build_pool(argv[0])
    target = Path(__file__).parent / "data" / POOLED_FILE
    atomic_write_bytes(target, (json.dumps(document, separators=(",", ":")) + "\n").encode())
    print(f"wrote {target}: {document['source']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
