"""512-bit vectors for XLA's CPU code on processors that have them (AVX-512).

XLA's CPU compiler emits 256-bit vector code by default (`--xla_cpu_prefer_vector_width=256`).
The fused pixel loop of `unprocess` is bound by arithmetic once noise is on (the counter hash and
the normal quantile of `g2r_jax.sensor`), so wider vectors pay. Measured on this project's 2-core
Xeon (benchmarks/README.md, "Noise"): 12-MP uint8 frames, batch 4, noise off 24.3 -> 22.8
ms/frame, noise on 42.2 -> 28.8 ms/frame. The operations are element-wise per lane, so the
outputs are the same bytes at either width (checked on three profiles, uint8 and float input).

`import g2r_jax` calls `prefer_wide_vectors()`: the flag is added to `XLA_FLAGS` when the CPU
reports `avx512f`, the user has not chosen a width, and `G2R_JAX_CPU_VECTOR_WIDTH` is unset. XLA
reads the variable when JAX first starts a backend, so it takes effect only if g2r_jax is
imported before the first JAX computation. Opt out with `G2R_JAX_CPU_VECTOR_WIDTH=256` (or any
`--xla_cpu_prefer_vector_width` in `XLA_FLAGS`).
"""

from __future__ import annotations

import os
import platform

from g2r_jax.runtime import xla_flags

NAME = "xla_cpu_prefer_vector_width"
OPT_OUT = "G2R_JAX_CPU_VECTOR_WIDTH"


def cpu_has_avx512(cpuinfo: str | None = None) -> bool:
    """Whether the processor reports AVX-512F (Linux /proc/cpuinfo; False where it cannot tell)."""
    if cpuinfo is None:
        if platform.system() != "Linux" or platform.machine().lower() not in ("x86_64", "amd64"):
            return False
        try:
            with open("/proc/cpuinfo", encoding="ascii", errors="replace") as handle:
                cpuinfo = handle.read(65536)
        except OSError:
            return False
    return any(line.startswith("flags") and "avx512f" in line.split() for line in cpuinfo.splitlines())


def chosen_width(cpuinfo: str | None = None) -> str | None:
    """The vector width XLA gets: the user's `--xla_cpu_prefer_vector_width` in XLA_FLAGS, else
    $G2R_JAX_CPU_VECTOR_WIDTH (128, 256 or 512), else 512 on an AVX-512 CPU, else None (XLA's
    default, 256)."""
    given = xla_flags.chosen(NAME)
    if given is not None:
        return given
    requested = os.environ.get(OPT_OUT, "").strip()
    if requested:
        return requested if requested in ("128", "256", "512") else None
    return "512" if cpu_has_avx512(cpuinfo) else None


def prefer_wide_vectors(cpuinfo: str | None = None) -> bool:
    """Add `--xla_cpu_prefer_vector_width=` (the `chosen_width`) to XLA_FLAGS unless the user
    already chose one, or there is no width to ask for. Returns whether XLA_FLAGS was changed."""
    if xla_flags.chosen(NAME) is not None:
        return False
    width = chosen_width(cpuinfo)
    return width is not None and xla_flags.add_flag(NAME, width)
