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

import os

FLAG = "--xla_gpu_deterministic_ops=true"


def request_deterministic_gpu_ops() -> bool:
    """Add FLAG to `XLA_FLAGS` unless the user already chose a value for it. XLA reads the variable
    when JAX first starts a backend, so call this before any JAX computation. Returns whether the
    flag was added."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_gpu_deterministic_ops" in flags:
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {FLAG}".strip()
    return True
