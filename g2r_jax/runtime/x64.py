"""A float64 context that works across JAX versions (for fitting and reference comparisons)."""

import jax


def enable_x64():
    """Context manager enabling 64-bit types (`jax.enable_x64` or the older experimental one)."""
    if hasattr(jax, "enable_x64"):
        return jax.enable_x64(True)
    from jax.experimental import enable_x64 as _legacy  # JAX < 0.5

    return _legacy()
