"""g2r_jax: computer-graphics images to RAW DNGs of one target camera.

    import jax, g2r_jax
    profile = g2r_jax.load_profile("s20fe_night")
    convert = jax.jit(jax.vmap(lambda key, image: g2r_jax.unprocess(key, image, profile)))
    mosaics, metadata = convert(jax.random.split(jax.random.PRNGKey(0), len(images)), images)

The names below are imported on first use (PEP 562), so that `import g2r_jax.cli...` and a
command's `--help` do not pay for importing JAX and colour-science.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "DngColourModel": "colour.dng_model", "camera_neutral_to_xy": "colour.dng_model",
    "camera_neutrals_to_xy": "colour.dng_model", "xy_to_camera_neutral": "colour.dng_model",
    "fit_profile": "profile.fitting", "IlluminantModel": "illuminants.distributions",
    "sample_neutrals": "illuminants.distributions", "ProfileError": "profile.checks",
    "SensorProfile": "profile.schema", "load_profile": "profile.schema", "save_profile": "profile.schema",
    "shipped_profiles": "profile.schema", "unprocess": "pipeline", "unprocess_batch": "pipeline",
}


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))


from g2r_jax.runtime.cpu_vectors import prefer_wide_vectors as _prefer_wide_vectors  # noqa: E402  (must run before JAX starts)

_prefer_wide_vectors()


def diagnose(*args, **kwargs):
    """Measured DNGs vs the profile's simulation: see `g2r_jax.audit.diagnose`."""
    from g2r_jax.audit import diagnose as _diagnose

    return _diagnose(*args, **kwargs)


__all__ = [
    "DngColourModel", "IlluminantModel", "ProfileError", "SensorProfile", "camera_neutral_to_xy",
    "camera_neutrals_to_xy", "diagnose", "fit_profile", "load_profile", "sample_neutrals", "save_profile",
    "shipped_profiles", "unprocess", "unprocess_batch", "xy_to_camera_neutral",
]

__version__ = "0.1.0"
