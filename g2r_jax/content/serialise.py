"""A profile's optional `content` block (JSON) <-> `ContentModel`.

    "content": {"family": "cast", "chroma_scale": 1.0, "tone_power": 1.0, "cast_scale": 0.0,
                "cast_target": [1.05, 0.99, 0.88], "apply_by_default": true,
                "target": {"chroma_spread": 0.21, "brightness": 0.1}, "source": "..."}

`apply_by_default` says whether conversion applies the model when not told (see the validation
page, docs/pages/validation/content_model.md, for why it is off unless measured to help).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from g2r_jax.content.model import FAMILIES, ContentModel, content_model

_KEYS = {"family", "chroma_scale", "tone_power", "cast_scale", "cast_target", "apply_by_default", "target", "source",
         "scene_casts", "scene_brightness", "texture"}


def content_to_dict(model: ContentModel) -> dict:
    """The `content` block of a profile document."""
    return {"family": model.family, "chroma_scale": float(model.chroma_scale), "tone_power": float(model.tone_power),
            "cast_scale": float(model.cast_scale), "cast_target": [float(v) for v in model.cast_target],
            "apply_by_default": bool(model.apply_by_default), "target": {k: float(v) for k, v in model.target},
            "source": model.source,
            **({} if model.family != "scenes" else {
                "scene_casts": [[round(float(v), 6) for v in row] for row in np.asarray(model.scene_casts)],
                "scene_brightness": [round(float(v), 6) for v in np.asarray(model.scene_brightness)]}),
            **({} if model.texture is None else {"texture": model.texture.to_dict()})}


def _raise(where: str, problem: str):
    raise ValueError(f"{where}: {problem}")


def _number(document: dict, key: str, fail) -> float:
    value = document.get(key, 1.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        fail(f"content.{key}", f"expected a finite number, got {value!r}")
    return float(value)


def content_from_dict(document, fail: Callable[[str, str], None] = _raise) -> ContentModel:
    """The `ContentModel` of a profile's `content` block; `fail(where, problem)` raises (the
    profile reader's, which names the file)."""
    if not isinstance(document, dict):
        fail("content", f"expected a JSON object, got {type(document).__name__}")
    unknown = sorted(set(document) - _KEYS)
    if unknown:
        fail("content", f"unknown keys {unknown}; expected some of {sorted(_KEYS)}")
    family = document.get("family")
    if family not in FAMILIES:
        fail("content.family", f"unknown family {family!r}; expected one of {', '.join(FAMILIES)}")
    scale, power = _number(document, "chroma_scale", fail), _number(document, "tone_power", fail)
    cast = _number(document, "cast_scale", fail)   # absent before the 'cast' family: 1, unchanged
    cast_target = document.get("cast_target", [1.0, 1.0, 1.0])
    if not (isinstance(cast_target, list) and len(cast_target) == 3
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in cast_target)):
        fail("content.cast_target", f"expected three numbers (a linear sRGB colour), got {cast_target!r}")
    target = document.get("target", {})
    if not isinstance(target, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                               for v in target.values()):
        fail("content.target", "expected an object of numbers (the real medians the model was fitted to)")
    by_default = document.get("apply_by_default", False)
    if not isinstance(by_default, bool):
        fail("content.apply_by_default", f"expected true or false, got {by_default!r}")
    table = _scene_table(document, family, fail)
    texture = None
    if document.get("texture") is not None:
        from g2r_jax.content.texture import texture_from_dict

        try:
            texture = texture_from_dict(document["texture"]) if isinstance(document["texture"], dict) else \
                fail("content.texture", "expected a JSON object (covariance, grid, files, source)")
        except ValueError as error:
            fail("content.texture", str(error))
    try:
        model = content_model(scale, power, cast_scale=cast, cast_target=cast_target, family=family, source=str(document.get("source", "")),
                              target={str(k): float(v) for k, v in target.items()}, apply_by_default=by_default,
                              texture=texture, **table)
    except ValueError as error:
        fail("content", str(error))
    return model


def _scene_table(document: dict, family: str, fail) -> dict:
    """The 'scenes' family's table, checked for shape and numbers ({} for the other families)."""
    if family != "scenes":
        return {}
    casts, brightness = document.get("scene_casts"), document.get("scene_brightness")
    if not (isinstance(casts, list) and casts and all(isinstance(row, list) and len(row) == 3 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in row) for row in casts)):
        fail("content.scene_casts", "expected a list of [r, g, b] colours (the scenes' casts, linear sRGB)")
    if not (isinstance(brightness, list) and len(brightness) == len(casts) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in brightness)):
        fail("content.scene_brightness", f"expected {len(casts)} numbers (one per scene in scene_casts)")
    return {"scene_casts": casts, "scene_brightness": brightness}
