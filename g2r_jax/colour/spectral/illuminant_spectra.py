"""Illuminants as spectra: the spectrum behind a sampled camera neutral.

A sampled illuminant is a camera neutral n (r/g, 1, b/g). Its spectrum is a base spectrum times a
smooth two-parameter filter whose camera response is exactly n:

    L(lambda) = base(lambda) * exp(a * t1(lambda) + b * t2(lambda))
    t1 = (lambda - 550 nm) / 150 nm               (a red-blue tilt: a shift along the locus)
    t2 = exp(-((lambda - 545 nm) / 50 nm)^2)       (a green-magenta tilt: Duv, off the locus)

Bases are the locus light at the neutral's CCT (Planck below 4000 K, CIE daylight above 5000 K,
as `g2r_jax.colour.CCT_to_xy`) and the lamp families the profile holds (CIE FL*, LED-*, HP*
tables). (a, b) solves two equations, log(R/G) and log(B/G) of S^T L equal to those of n, by
Newton's method with a fixed number of steps (jit/vmap-able). Among the bases the one needing
the smallest filter (|a|^2 + |b|^2, lamps only where they beat the locus by `LAMP_MARGIN`) is the
illuminant: a lamp family is used only where a locus light would need a strong filter.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.colour.spectral import tables

NEWTON_STEPS = 12
LAMP_MARGIN = 0.05     # a lamp must need a filter this much weaker (in |a|^2 + |b|^2) than the locus
TILT_BASIS = np.stack([(tables.WAVELENGTHS - 550.0) / 150.0,
                       np.exp(-(((tables.WAVELENGTHS - 545.0) / 50.0) ** 2))])


def locus_base(cct):
    """The locus light at `cct` (K), linear interpolation of `tables.locus_table` in mired."""
    table = jnp.asarray(tables.locus_table(), jnp.result_type(cct, jnp.float32))
    position = (1e6 / cct - tables.LOCUS_MIRED[0]) / (tables.LOCUS_MIRED[1] - tables.LOCUS_MIRED[0])
    position = jnp.clip(position, 0.0, len(tables.LOCUS_MIRED) - 1.0)
    low = jnp.clip(jnp.floor(position).astype(jnp.int32), 0, len(tables.LOCUS_MIRED) - 2)
    fraction = position - low
    return (1 - fraction) * table[low] + fraction * table[low + 1]


def filtered(base, tilt):
    return base * jnp.exp(tilt @ jnp.asarray(TILT_BASIS, base.dtype))


def _log_chromaticity(response):
    return jnp.log(jnp.maximum(response[jnp.array([0, 2])], 1e-30)) - jnp.log(jnp.maximum(response[1], 1e-30))


def solve_filter(base, neutral, sensitivities):
    """(a, b) such that the camera response of `filtered(base, (a, b))` is `neutral` (any scale).

    **Returns:** `(tilt (2,), residual)`: residual is the remaining |log-chromaticity| error.
    """
    target = _log_chromaticity(neutral)

    def residual(tilt):
        return _log_chromaticity(filtered(base, tilt) @ sensitivities) - target

    def step(tilt, _):
        value = residual(tilt)
        jacobian = jax.jacfwd(residual)(tilt)
        update = jnp.linalg.solve(jacobian + 1e-9 * jnp.eye(2, dtype=tilt.dtype), value)
        length = jnp.linalg.norm(update)
        return tilt - update * jnp.minimum(1.0, 2.0 / jnp.maximum(length, 1e-12)), None

    tilt, _ = jax.lax.scan(step, jnp.zeros(2, base.dtype), None, length=NEWTON_STEPS)
    return tilt, jnp.linalg.norm(residual(tilt))


def candidate_bases(cct, lamp_spectra):
    """(1 + F, 81): the locus light at `cct`, then the lamp families (each scaled to max 1)."""
    locus = locus_base(cct)
    return jnp.concatenate([locus[None], lamp_spectra.astype(locus.dtype)], axis=0)


def filter_costs(neutral, cct, sensitivities, lamp_spectra):
    """For every candidate base: its filter (1 + F, 2) and cost |a|^2 + |b|^2 (+ a penalty where
    the solve did not reach the neutral); the lamps' costs include `LAMP_MARGIN`."""
    bases = candidate_bases(cct, lamp_spectra)
    tilts, residuals = jax.vmap(lambda base: solve_filter(base, neutral, sensitivities))(bases)
    costs = jnp.sum(tilts**2, axis=-1) + 1e3 * residuals
    costs = costs.at[1:].add(LAMP_MARGIN)
    return bases, tilts, costs


def illuminant_spectrum(neutral, cct, sensitivities, lamp_spectra):
    """The spectrum of the illuminant with camera response `neutral` (see the module docstring).

    **Returns:** `(spectrum (81,), family index (0 = locus, i = lamp i - 1), tilt (2,))`; the
    spectrum is scaled so that its green response is 1.
    """
    bases, tilts, costs = filter_costs(neutral, cct, sensitivities, lamp_spectra)
    family = jnp.argmin(costs)
    spectrum = filtered(bases[family], tilts[family])
    return spectrum / (spectrum @ sensitivities[:, 1]), family, tilts[family]


# ------------------------------------------------------------------------- fitting (numpy edge)

def choose_lamp_families(chromaticities, cct, sensitivities, *, candidates=tables.LAMP_FAMILIES,
                         min_share: float = 0.05) -> tuple:
    """The lamp families a set of measured illuminants demands.

    For each measured neutral (r/g, b/g) with white-point CCT `cct`, the cheapest base among the
    locus and all `candidates` (`filter_costs`); a family is kept when it is the cheapest for at
    least `min_share` of the neutrals (and at least two). Returns family names (maybe empty).
    """
    chromaticities = np.asarray(chromaticities, np.float64)
    neutrals = np.stack([chromaticities[:, 0], np.ones(len(chromaticities)), chromaticities[:, 1]], -1)
    lamps = jnp.asarray(np.stack([tables.illuminant(n) for n in candidates]), jnp.float32)
    S = jnp.asarray(sensitivities, jnp.float32)
    costs = jax.jit(jax.vmap(lambda n, t: filter_costs(n, t, S, lamps)[2]))(
        jnp.asarray(neutrals, jnp.float32), jnp.asarray(np.asarray(cct), jnp.float32))
    best = np.asarray(jnp.argmin(costs, axis=1))
    counts = np.bincount(best, minlength=1 + len(candidates))
    needed = max(2, int(np.ceil(min_share * len(neutrals))))
    return tuple(name for i, name in enumerate(candidates) if counts[i + 1] >= needed)
