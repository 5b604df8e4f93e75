"""Compiled programs kept within the kernel's limit on a process's memory mappings.

XLA's CPU backend links every compiled program into memory of its own, a few mappings per
program (JAX 0.10 on Linux: an eager `unprocess` of a new image shape compiles about 170 small
programs and adds about 300 mappings, the jitted one about 770). Linux refuses a
process more than `vm.max_map_count` mappings (65530 by default). Past it LLVM cannot allocate a
new program's sections: the process aborts in `RuntimeDyldImpl::emitSection`, or segfaults while
reading a program from the persistent compilation cache. A process that compiles programs for many
shapes and lives long (a test run, a benchmark over many cameras) calls `release_if_crowded()`
between units of work; above `SHARE` of the limit it drops JAX's compiled programs
(`jax.clear_caches()`), which are compiled again, or read from the persistent cache, when next
needed. Nothing is done where `/proc` does not tell (macOS, Windows).
"""

from __future__ import annotations

from pathlib import Path

DEFAULT_LIMIT = 65530       # Linux's default vm.max_map_count
SHARE = 0.4                 # of the limit: leaves room for a unit of work that compiles many programs


def mapping_limit() -> int | None:
    """The kernel's limit on one process's memory mappings (`/proc/sys/vm/max_map_count`); None
    where there is no such file."""
    try:
        return int(Path("/proc/sys/vm/max_map_count").read_text().strip())
    except (OSError, ValueError):
        return None


def mapping_count() -> int | None:
    """This process's memory mappings now (lines of `/proc/self/maps`); None where it cannot tell."""
    try:
        with open("/proc/self/maps", "rb") as maps:
            return maps.read().count(b"\n")
    except OSError:
        return None


def release_if_crowded(share: float = SHARE) -> bool:
    """Drop JAX's compiled programs when this process holds more than `share` of the mapping
    limit; returns whether it did."""
    count, limit = mapping_count(), mapping_limit()
    if count is None or count <= share * (limit or DEFAULT_LIMIT):
        return False
    import gc

    import jax

    jax.clear_caches()
    gc.collect()
    return True
