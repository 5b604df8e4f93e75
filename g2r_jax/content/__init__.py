"""The content model (issue 32): what the CG scenes get wrong about the world, and a transform in
scene-linear light, before the camera, that moves them toward the camera's real scenes.

Layer: above `illuminants`, below `profile` and `pipeline` (imports io, measure, sensor, colour,
illuminants only).

    real = statistics(white_balanced_camera_rgb(thumbnails, neutrals))    # the camera's own files
    to_camera = srgb_to_camera_matrices(typical_neutral[None], profile.colour)[0]
    model = fit_content_model(real, cg_sample=cg_linear_images, to_camera=to_camera)   # family 'chroma'
    adapted = apply(model, cg_linear_image)                  # jit / vmap as you like
"""

from g2r_jax.content.fitting import fit_content_model, prior_cast_model, prior_scenes_model
from g2r_jax.content.from_files import content_model_from_files, mosaic_thumbnail
from g2r_jax.content.model import (CAST_KEPT, FAMILIES, ContentModel, apply, as_cast, as_matrix, content_model, describe,
                                   grid_count, identity, mean_grid, pixel_factor, scenes_split, with_default)
from g2r_jax.content.real_images import (camera_rgb_to_linear_srgb, srgb_to_camera_matrices,
                                       srgb_to_white_balanced_camera, white_balanced_camera_rgb)
from g2r_jax.content.scene_statistics import NAMES, ContentStatistics, statistics
from g2r_jax.content.serialise import content_from_dict, content_to_dict

__all__ = ["CAST_KEPT", "FAMILIES", "NAMES", "ContentModel", "ContentStatistics", "apply", "as_cast", "as_matrix",
           "camera_rgb_to_linear_srgb", "content_from_dict", "content_model", "content_model_from_files",
           "content_to_dict", "describe", "fit_content_model", "grid_count", "identity", "mean_grid",
           "mosaic_thumbnail", "pixel_factor", "prior_cast_model", "prior_scenes_model", "scenes_split",
           "srgb_to_camera_matrices", "srgb_to_white_balanced_camera", "statistics", "white_balanced_camera_rgb",
           "with_default"]
