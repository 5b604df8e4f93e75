"""Arrays made on the host and copied to the device without a compiled program.

`jnp.asarray(x)` and `jnp.asarray(x, dtype)` of a numpy array run a small jitted program on the
device (JAX 0.10: `jit(stage)`, and a conversion when the dtype differs), traced, lowered and
compiled (or read from the compilation cache) the first time in a process for each shape: 5 to
45 ms each. A profile holds about sixteen arrays: 0.13 s of a command's start-up on the 2-core
development machine (docs/pages/validation/startup.md). Converting with numpy (IEEE
round-to-nearest-even, as XLA) and `jax.device_put` give the same values with a plain copy."""

from __future__ import annotations

import jax
import numpy as np


def device_array(values, dtype=None):
    """`values` as a JAX array (of `dtype` when given), converted by numpy on the host."""
    return jax.device_put(np.asarray(values, dtype=None if dtype is None else np.dtype(dtype)))
