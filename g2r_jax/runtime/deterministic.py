"""Bit-reproducible programs on GPUs for the commands: XLA's deterministic GPU operations.

On a GPU, XLA picks some kernels (matrix products among them) by timing candidates when it
compiles a program, so two compilations of one program may round differently. Measured on an
NVIDIA H100 (benchmarks/README.md, "GPU"): the white points of `batch_conditions` differed in
the last bit between separately compiled batch sizes in 1-3 of 36 (batch, offset) cases per
run, and in none with `--xla_gpu_deterministic_ops=true`, at the same throughput within the
runs' spread. The commands turn it on so that a file's bytes do not depend on the batch it was
converted in (as on a CPU, where programs are deterministic anyway); library users on a GPU set
`XLA_FLAGS=--xla_gpu_deterministic_ops=true` themselves before JAX starts.
"""

from __future__ import annotations

from g2r_jax.runtime.xla_flags import add_flag


def request_deterministic_gpu_ops() -> bool:
    """Add `--xla_gpu_deterministic_ops=true` to `XLA_FLAGS` unless the user already chose a
    value for it (`xla_flags.add_flag`). Call this before any JAX computation. Returns whether
    the flag was added."""
    return add_flag("xla_gpu_deterministic_ops", "true")
