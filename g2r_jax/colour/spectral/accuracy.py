"""Colour accuracy of the colour models against a camera with known spectral sensitivities.

The experiment of issue 11: a camera with measured sensitivities S is the ground truth. The scene
is the ColorChecker (24 reflectances R) under a light L; the camera records S^T diag(L) R. The CG
image is the scene's white-balanced colorimetric rendition: the patches' sRGB under D65. Each
colour model maps that sRGB image and the light's camera neutral (S^T L) to camera RGB; the error
is the angle between predicted and recorded camera RGB of the 18 chromatic patches (degrees),
independent of exposure.

Models: `matrix` (the DNG inverse of `unprocess`, colour="matrix", with the camera's Adobe
matrices), `spectral` (Mallett-Yuksel upsampling x light x S, colour="spectral"), `jakob2019`
(Jakob-Hanika sigmoid-polynomial upsampling x light x S). The spectral models take either the
true light or the light `unprocess` infers from the neutral (`illuminant_spectra`).
numpy + jax; used by tests/test_spectral.py and benchmarks/spectral_colour.py.
"""

from __future__ import annotations

import functools

import numpy as np

from g2r_jax.colour.charts import chart_linear_srgb
from g2r_jax.colour.spectral import tables
from g2r_jax.measure import angular_error_degrees

CHROMATIC_PATCHES = slice(0, 18)


def locus_lights() -> dict:
    """Seven lights on the Planckian/daylight locus, 2500 K to D75."""
    return {"2500 K": tables.blackbody(2500.0), "A": tables.illuminant("A"), "3500 K": tables.blackbody(3500.0),
            "4500 K": tables.blackbody(4500.0), "D50": tables.illuminant("D50"), "D65": tables.illuminant("D65"),
            "D75": tables.illuminant("D75")}


def _equal_luminance_mix(first, second):
    y = tables.cmfs()[:, 1]
    return 0.5 * first / (first @ y) + 0.5 * second / (second @ y)


def off_locus_lights() -> dict:
    """Lamps off the locus (CIE FL2, FL11, LED-B3, HP1 sodium) and two equal-luminance mixtures:
    a street (HP1 + LED-B3) and an office by a window (FL11 + D65)."""
    return {"FL2": tables.illuminant("FL2"), "FL11": tables.illuminant("FL11"), "LED-B3": tables.illuminant("LED-B3"),
            "HP1": tables.illuminant("HP1"),
            "HP1+LED-B3": _equal_luminance_mix(tables.illuminant("HP1"), tables.illuminant("LED-B3")),
            "FL11+D65": _equal_luminance_mix(tables.illuminant("FL11"), tables.illuminant("D65"))}


def recorded(sensitivities, light) -> np.ndarray:
    """The camera's ground truth (24, 3): S^T diag(L) R for each patch."""
    return tables.colour_checker() @ (np.asarray(light)[:, None] * np.asarray(sensitivities))


def neutral_of(sensitivities, light) -> np.ndarray:
    response = np.asarray(light) @ np.asarray(sensitivities)
    return response / response[1]


def predict_matrix(srgb, neutral, colour_model) -> np.ndarray:
    """Camera RGB by the matrix model, exactly as `unprocess(colour="matrix")` (float64)."""
    import jax
    import jax.numpy as jnp

    from g2r_jax.colour import dng_model as dng
    from g2r_jax.runtime.x64 import enable_x64
    from g2r_jax.colour.camera_rgb import matrix_srgb_to_white_balanced_camera

    with enable_x64():
        model = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float64) if hasattr(a, "dtype") else a, colour_model)
        n = jnp.asarray(neutral, jnp.float64)
        xy, _ = dng.camera_neutral_to_xy(n, model)
        matrix = np.asarray(matrix_srgb_to_white_balanced_camera(xy, n, model))
    return (np.asarray(srgb) @ matrix.T) * np.asarray(neutral)


def predict_spectral(reflectances, light, sensitivities) -> np.ndarray:
    """Camera RGB of upsampled reflectances (N, 81) under `light` (81,)."""
    return np.asarray(reflectances) @ (np.asarray(light)[:, None] * np.asarray(sensitivities))


def mallett_yuksel_reflectances(srgb) -> np.ndarray:
    return np.asarray(srgb) @ tables.mallett_yuksel_basis().T


@functools.lru_cache(maxsize=None)
def _colour_checker_jakob_hanika() -> np.ndarray:
    return jakob_hanika_reflectances(chart_linear_srgb())


def jakob_hanika_reflectances(srgb) -> np.ndarray:
    """Jakob & Hanika (2019) sigmoid-polynomial reflectances fitted (colour-science's optimiser)
    to each colour's XYZ under D65 (out-of-gamut colours get the nearest reachable spectrum)."""
    from g2r_jax.colour.spectral.upsampling import jakob_hanika_coefficients_for_srgb, jakob_hanika_spectra

    return np.asarray(jakob_hanika_spectra(jakob_hanika_coefficients_for_srgb(srgb)))


def inferred_light(neutral, sensitivities, colour_model, lamp_families=()) -> np.ndarray:
    """The light `unprocess(colour="spectral")` infers from the camera neutral."""
    import jax
    import jax.numpy as jnp

    from g2r_jax.colour import conversions as _colour
    from g2r_jax.colour import dng_model as dng
    from g2r_jax.colour.spectral.illuminant_spectra import illuminant_spectrum

    xy, _ = dng.camera_neutral_to_xy(jnp.asarray(neutral, jnp.float32), colour_model)
    lamps = (np.stack([tables.illuminant(n) for n in lamp_families]) if lamp_families
             else np.zeros((0, len(tables.WAVELENGTHS))))
    spectrum, _, _ = jax.jit(illuminant_spectrum)(jnp.asarray(neutral, jnp.float32), _colour.xy_to_CCT(xy),
                                         jnp.asarray(sensitivities, jnp.float32), jnp.asarray(lamps, jnp.float32))
    return np.asarray(spectrum, np.float64)


def jakob_hanika_lattice_reflectances(srgb) -> np.ndarray:
    """Jakob-Hanika reflectances as `unprocess(colour="spectral-jakob2019")` gets them: trilinear
    interpolation of the shipped lattice (the camera response is linear in the reflectance, so
    interpolating reflectances or responses is the same)."""
    import jax.numpy as jnp

    from g2r_jax.colour.spectral.upsampling import lattice, trilinear

    nodes, reflectances = lattice()
    return np.asarray(trilinear(jnp.asarray(reflectances), jnp.asarray(np.clip(srgb, 0, 1)), jnp.asarray(nodes)),
                      np.float64)


def colour_table(sensitivities, colour_model, *, lamp_families=tables.LAMP_FAMILIES, jakob_hanika="direct",
                 simulated_sensitivities=None) -> dict:
    """Chromatic mean angular error per light and model.

    **Arguments:** `sensitivities` (81, 3): the ground-truth camera; `colour_model`: its DNG
    matrices (`DngColourModel`); `lamp_families`: the families the inferred light may use;
    `simulated_sensitivities`: the sensitivities the spectral model uses (default: the true ones;
    pass estimated ones to measure the estimate); `jakob_hanika`: 'direct' (colour-science's
    optimiser per patch), 'lattice' (the shipped lattice, as `unprocess` does), 'both' or None.

    **Returns:** {model: {light: (mean, max)}} for models `matrix`, `spectral (true light)`,
    `spectral (inferred light)`, and with `jakob_hanika` `jakob2019 (true light)`,
    `jakob2019 (inferred light)` (and `jakob2019 lattice (...)`).
    """
    truth_s = np.asarray(sensitivities, np.float64)
    model_s = truth_s if simulated_sensitivities is None else np.asarray(simulated_sensitivities, np.float64)
    srgb = chart_linear_srgb()
    reflectances = {"spectral": mallett_yuksel_reflectances(srgb)}
    if jakob_hanika in ("direct", "both"):
        reflectances["jakob2019"] = _colour_checker_jakob_hanika()
    if jakob_hanika in ("lattice", "both"):
        reflectances["jakob2019 lattice"] = jakob_hanika_lattice_reflectances(srgb)
    results = {}
    for name, light in {**locus_lights(), **off_locus_lights()}.items():
        truth = recorded(truth_s, light)[CHROMATIC_PATCHES]
        neutral = neutral_of(truth_s, light)

        def score(predicted):
            errors = angular_error_degrees(predicted[CHROMATIC_PATCHES], truth, invalid="nan")
            return float(errors.mean()), float(errors.max())

        results.setdefault("matrix", {})[name] = score(predict_matrix(srgb, neutral, colour_model))
        guess = inferred_light(neutral, model_s, colour_model, lamp_families)
        for method, r in reflectances.items():
            results.setdefault(f"{method} (true light)", {})[name] = score(predict_spectral(r, light, model_s))
            results.setdefault(f"{method} (inferred light)", {})[name] = score(predict_spectral(r, guess, model_s))
    return results


def summarise(table: dict) -> dict:
    """{model: {"locus": mean, "off": mean, "HP1": (mean, max)}} over the lights of `colour_table`."""
    on, off = list(locus_lights()), list(off_locus_lights())
    return {model: {"locus": float(np.mean([rows[l][0] for l in on])),
                    "off": float(np.mean([rows[l][0] for l in off])),
                    "HP1": rows["HP1"]} for model, rows in table.items()}
