"""g2r_jax as `g2r-fit-profile` makes it from a camera's real files, for the training sets of
every downstream task (the colour check's rows, the ISP task's pairs, the check's comparison of
contents): the profile's illuminant model fitted to the files' lights (`fitted_illuminants`), the
content model fitted to their scenes (`candidate_model`; `FITTED`, the family the rows use when
the profile has none; the candidates are named in `downstream.illuminant.content_rows`), and CG
views through a content model (`adapted_views`). Protocol and measurement:
docs/pages/validation/content_model.md.
"""

from __future__ import annotations

import functools

import numpy as np

# What the rows use when the profile has none: the model g2r-fit-profile fits (finding 4: the
# scenes' spread beat the one median cast on the training folds' inner third, on six cameras)
FITTED = "scenes"
_APPLY_CHUNK = 100                # views per compiled call of `content.apply`


def fitted_illuminants(profile, illuminants: np.ndarray, kind: str = "auto", seed: int = 0):
    """The profile with its illuminant model fitted to `illuminants` (N, 3) as `g2r-fit-profile`
    fits it to a folder's as-shot neutrals."""
    from g2r_jax.illuminants.distributions import neutral_to_chromaticity
    from g2r_jax.profile.fitting import illuminant_model_for
    from g2r_jax.profile.schema import replace

    chromaticities = neutral_to_chromaticity(np.asarray(illuminants, np.float64))
    return replace(profile, illuminants=illuminant_model_for(chromaticities, profile.colour, kind, seed))


def adapted_views(model, views: np.ndarray, seed: int = 0) -> np.ndarray:
    """Linear sRGB views (n, H, W, 3) through the content model (`g2r_jax.content.apply`, jit),
    in chunks of `_APPLY_CHUNK`; the 'scenes' family draws each view's scene from `seed`."""
    import dataclasses

    # The model's description (source, target, texture) is static in its pytree: without it, one compiled
    # program serves every fold's model.
    model = dataclasses.replace(model, source="", target=(), texture=None)
    views = np.asarray(views, np.float32)
    draws = np.random.default_rng(seed).uniform(size=len(views)).astype(np.float32)
    if model.family != "scenes":
        draws = [None] * len(views)
    return np.concatenate([np.asarray(_jitted_apply()(model, views[i:i + _APPLY_CHUNK],
                                                      None if draws[0] is None else draws[i:i + _APPLY_CHUNK]))
                           for i in range(0, len(views), _APPLY_CHUNK)])


@functools.lru_cache(maxsize=1)
def _jitted_apply():
    import jax

    from g2r_jax.content import apply

    return jax.jit(apply)


def candidate_model(name: str, images: np.ndarray, lights: np.ndarray, views: np.ndarray, profile,
                    prior_medians: dict | None = None, prior_covariance=None):
    """The content model of candidate `name`: 'chroma@S' a chroma scale S given, 'cast@C' a kept
    cast C given (family 'cast'); otherwise a family
    of `g2r_jax.content.FAMILIES` fitted to real thumbnails `images` (white-balanced by `lights`,
    as a DNG's AsShotNeutral would) and a sample of the CG `views`, in the camera's white-balanced
    RGB at the median light (`fit_content_model`, its prior of real scenes `prior_medians` when
    given, and for 'scenes' the spread of its scenes `prior_covariance`; 'identity' fits to the identity)."""
    from g2r_jax import content

    family, given, value = name.partition("@")
    if given and family in ("chroma", "cast"):
        try:
            value = float(value)
        except ValueError:
            raise ValueError(f"content candidate {name!r}: expected {family}@S with S a number in [0, 1]") from None
        if family == "cast":
            return content.content_model(cast_scale=value, family="cast", source="given")
        return content.content_model(value, family="chroma", source="given")
    if name not in content.FAMILIES:
        raise ValueError(f"unknown content candidate {name!r}; expected one of "
                         f"{', '.join(content.FAMILIES)}, chroma@S or cast@C")
    real = content.statistics(content.white_balanced_camera_rgb(images, lights), source="training folds")
    neutral = np.median(lights / lights[:, 1:2], axis=0)
    to_camera = content.srgb_to_camera_matrices(neutral[None], profile.colour)[0]
    return content.fit_content_model(real, family=name, cg_sample=views, to_camera=to_camera,
                                     prior_medians=prior_medians, prior_covariance=prior_covariance)
