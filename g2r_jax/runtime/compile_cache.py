"""JAX's persistent compilation cache for the commands: compiled programs are kept on disk, so
every run after the first skips XLA compilation (seconds per program on a CPU).

Location: `$G2R_JAX_CACHE_DIR` if set, else `$XDG_CACHE_HOME/g2r_jax/jax`, else
`~/.cache/g2r_jax/jax`. Opt out with `--no-compile-cache` on any command or
`G2R_JAX_NO_COMPILE_CACHE=1`. The cache is JAX's own (`jax_compilation_cache_dir`); entries are
keyed by the program, the JAX/XLA version and the device, and the folder can be deleted at any
time; it keeps at most `MAX_BYTES` (the least recently used programs go first), and every read and
write holds JAX's file lock, so that processes running at once never read a half-written entry. A
cache that cannot be created or written is skipped with one line on stderr.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DISABLE_VARIABLE = "G2R_JAX_NO_COMPILE_CACHE"
LOCATION_VARIABLE = "G2R_JAX_CACHE_DIR"
MAX_BYTES = 2 * 2 ** 30     # the compilation cache's cap; least recently used programs go first


def default_location() -> Path:
    """The cache folder the commands use (see the module docstring)."""
    if os.environ.get(LOCATION_VARIABLE):
        return Path(os.environ[LOCATION_VARIABLE]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "g2r_jax" / "jax"


def disabled_by_environment() -> bool:
    return os.environ.get(DISABLE_VARIABLE, "").strip().lower() not in ("", "0", "false", "no")


def enable(location: Path | str | None = None, *, program: str = "g2r_jax") -> Path | None:
    """Turn on JAX's persistent compilation cache at `location` (default `default_location()`),
    caching every program however quick its compilation. Returns the folder, or None when it
    could not be used (reported on stderr) or the environment opts out. Call it before the first
    compilation; already-compiled programs are not written."""
    if disabled_by_environment():
        return None
    folder = Path(location).expanduser() if location is not None else default_location()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as error:
        print(f"{program}: warning: compilation cache {folder} not usable ({error.strerror or error}); "
              f"compiling without it", file=sys.stderr)
        return None
    # A size cap turns on JAX's file lock around every read and write of the cache: without it an
    # entry is written in place, and a second process reading it half-written crashed in XLA's
    # deserialisation (a segmentation fault seen with two test workers converting at once).
    settings = {"jax_compilation_cache_dir": str(folder), "jax_persistent_cache_min_compile_time_secs": 0.0,
                "jax_persistent_cache_min_entry_size_bytes": 0, "jax_compilation_cache_max_size": MAX_BYTES}
    if "jax" in sys.modules:
        import jax

        for option, value in settings.items():
            jax.config.update(option, value)
    else:   # read by JAX when it is imported: a command's early errors need not import it
        for option, value in settings.items():
            os.environ[option.upper()] = str(value)
    return folder
