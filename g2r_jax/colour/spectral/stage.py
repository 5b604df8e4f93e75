"""The spectral colour stage of `unprocess`: a sibling of the matrix stage (`unprocess.MATRIX_STAGE`).

A colour stage has two pure functions, called by `unprocess` at its steps 3-4 and 5:
- `conditions(neutral, profile, recipe)` -> dict with `neutral` (the AsShotNeutral), `xy`, `cct`,
  `converged` and what its `mosaic` needs;
- `mosaic(linear, conditions, cfa_pattern, highlight_safe)` -> un-white-balanced camera RGB,
  mosaicked, with white at 1 in the strongest channel.

Spectral model (issue 11): the sampled neutral becomes a light spectrum L whose camera response
is that neutral (`illuminant_spectra`); the image's linear sRGB becomes reflectance (`upsampling`);
camera RGB = S^T diag(L) reflectance. With the linear three-basis upsampling this is one 3x3 per
image, S^T diag(L) B, so the pixel work is the matrix stage's (`mosaic_camera_rgb`); with the
Jakob-Hanika lattice it is a per-image table of camera RGB at the lattice nodes, interpolated
per pixel. The written DNG keeps the profile's colour tags; its AsShotNeutral is S^T L.

Design for two lights in one image (not built): with a per-pixel mixing weight m(x) in [0, 1],
camera RGB = (1 - m) S^T diag(L1) B rgb + m S^T diag(L2) B rgb, i.e. two 3x3 matrices per image
and one weight map (a smooth random field or a rendered light mask); conditions would carry both
matrices and the neutrals of both lights, AsShotNeutral the response of the dominant light
(camera white balance sees one light), and the metadata both, for two-illuminant training targets.
"""

from __future__ import annotations

import jax.numpy as jnp

from g2r_jax.colour import conversions as _colour
from g2r_jax.colour import dng_model as _dng
from g2r_jax import sensor as _sensor
from g2r_jax.colour.spectral import tables
from g2r_jax.colour.spectral.illuminant_spectra import illuminant_spectrum

EXTRA_METADATA = ("illuminant_family", "illuminant_spectrum")


def _require(profile):
    if getattr(profile, "spectral", None) is None:
        raise ValueError(f"profile {profile.info.name!r} has no spectral sensitivities: add them with "
                         "g2r-fit-profile --sensitivities FILE, or g2r_jax.profile.editing.attach_spectral(profile)")
    return profile.spectral


def light_of(neutral, profile):
    """White point, CCT and the illuminant spectrum of a sampled neutral (shared by both upsamplings)."""
    model = _require(profile)
    xy, converged = _dng.camera_neutral_to_xy(neutral, profile.colour, throw=False)
    cct = _colour.xy_to_CCT(xy)
    spectrum, family, _ = illuminant_spectrum(neutral, cct, model.sensitivities, model.lamp_spectra)
    weighted = spectrum[:, None] * model.sensitivities                      # (81, 3): diag(L) S
    response = jnp.sum(weighted, axis=0)                                    # S^T L, G = 1
    return {"neutral": response / response[1], "xy": xy, "cct": cct, "converged": converged,
            "illuminant_family": family, "illuminant_spectrum": spectrum, "weighted": weighted,
            "response": response}


def linear_conditions(neutral, profile, recipe: str = "dng"):
    """Mallett-Yuksel: srgb_to_wb_camera = S^T diag(L) B / (S^T L) row-wise (rows sum to 1)."""
    light = light_of(neutral, profile)
    basis = jnp.asarray(tables.mallett_yuksel_basis(), light["weighted"].dtype)
    srgb_to_camera = light.pop("weighted").T @ basis
    light["srgb_to_wb_camera"] = srgb_to_camera / light.pop("response")[:, None]
    return light


def linear_mosaic(linear, conditions, cfa_pattern, highlight_safe: bool):
    from g2r_jax.colour.camera_rgb import mosaic_camera_rgb

    return mosaic_camera_rgb(linear, conditions["srgb_to_wb_camera"], conditions["gains"], cfa_pattern, highlight_safe)


def jakob_hanika_conditions(neutral, profile, recipe: str = "dng"):
    """Jakob-Hanika: white-balanced camera RGB at every node of the shipped lattice (n, n, n, 3)."""
    from g2r_jax.colour.spectral.upsampling import lattice

    light = light_of(neutral, profile)
    nodes, reflectances = lattice()
    weighted = light.pop("weighted")
    table = jnp.asarray(reflectances, weighted.dtype) @ weighted / light.pop("response")
    light["camera_lattice"] = table
    # the matrix of the linear method, for the highlight test of `mosaic` (grey level of a pixel)
    basis = jnp.asarray(tables.mallett_yuksel_basis(), weighted.dtype)
    light["srgb_to_wb_camera"] = (weighted.T @ basis) / weighted.sum(0)[:, None]
    return light


def jakob_hanika_mosaic(linear, conditions, cfa_pattern, highlight_safe: bool):
    """Camera RGB by trilinear interpolation of the node table, only the channel each pixel keeps
    (8 scalar gathers a pixel from a flat (nodes^3 * 4) table: one column per tile position).
    Values above 1 (HDR input) are scaled into the cube and back (a brighter surface of the same
    colour). The highlight test uses the grey level of the linear method's matrix."""
    from g2r_jax.colour.camera_rgb import HIGHLIGHT_INFLECTION, dot_channels
    from g2r_jax.colour.spectral.upsampling import lattice

    nodes, _ = lattice()
    n = len(nodes)
    shape = linear.shape[:2]
    per_position = conditions["camera_lattice"][..., cfa_pattern].reshape(-1)          # (n^3 * 4,)
    scale = jnp.maximum(jnp.max(linear, axis=-1), 1.0)
    position = jnp.clip(linear / scale[..., None], 0.0, 1.0) * (n - 1)
    low = jnp.clip(jnp.floor(position), 0, n - 2)
    fraction = position - low
    low = low.astype(jnp.int32)
    tile = _sensor.per_position(jnp.arange(4, dtype=jnp.int32), shape)
    base = ((low[..., 0] * n + low[..., 1]) * n + low[..., 2]) * 4 + tile
    kept = 0.0
    for corner in range(8):
        dr, dg, db = (corner >> 2) & 1, (corner >> 1) & 1, corner & 1
        weight = ((fraction[..., 0] if dr else 1 - fraction[..., 0]) * (fraction[..., 1] if dg else 1 - fraction[..., 1])
                  * (fraction[..., 2] if db else 1 - fraction[..., 2]))
        kept = kept + weight * per_position[base + ((dr * n + dg) * n + db) * 4]
    kept = kept * scale
    gain = _sensor.per_position(conditions["gains"][cfa_pattern], shape)
    if not highlight_safe:
        return kept * gain
    gray = dot_channels(linear, jnp.mean(conditions["srgb_to_wb_camera"], axis=0))
    mask = (jnp.maximum(gray - HIGHLIGHT_INFLECTION, 0.0) / (1.0 - HIGHLIGHT_INFLECTION)) ** 2
    return kept * jnp.maximum(mask + (1.0 - mask) * gain, gain)


STAGES = {
    "spectral": (linear_conditions, linear_mosaic),
    "spectral-jakob2019": (jakob_hanika_conditions, jakob_hanika_mosaic),
}
