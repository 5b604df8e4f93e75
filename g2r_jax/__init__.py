"""g2r_jax: computer-graphics images to RAW DNGs of one target camera.

    import jax, g2r_jax
    profile = g2r_jax.load_profile("s20fe_night")
    convert = jax.jit(jax.vmap(lambda key, image: g2r_jax.unprocess(key, image, profile)))
    mosaics, metadata = convert(jax.random.split(jax.random.PRNGKey(0), len(images)), images)
"""

from .dng import DngColourModel, camera_neutral_to_xy, camera_neutrals_to_xy, xy_to_camera_neutral
from .fit import fit_profile
from .illuminants import IlluminantModel, sample_neutrals
from .profile import ProfileError, SensorProfile, load_profile, save_profile, shipped_profiles
from .unprocess import unprocess, unprocess_batch


def diagnose(*args, **kwargs):
    """Measured DNGs vs the profile's simulation: see `g2r_jax.audit.diagnose`."""
    from .audit import diagnose as _diagnose

    return _diagnose(*args, **kwargs)


__all__ = [
    "DngColourModel", "IlluminantModel", "ProfileError", "SensorProfile", "camera_neutral_to_xy",
    "camera_neutrals_to_xy", "diagnose", "fit_profile", "load_profile", "sample_neutrals", "save_profile",
    "shipped_profiles", "unprocess", "unprocess_batch", "xy_to_camera_neutral",
]

__version__ = "0.1.0"
