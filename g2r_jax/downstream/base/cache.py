"""The downstream check's store of finished trainings (issue 52): each unit's outcome (a trained
estimator's estimates of the test fold's real images) kept on disk under a key of everything it
depends on, so that a second run of `g2r-downstream` on the same inputs, or one that adds a row or
a task, trains only what is new.

The key (`key_of`) is a SHA-256 over: the code (every source file of the `g2r_jax` package,
`code_digest`: a changed line anywhere retrains), the real images and their labels, the CG images,
the profile (its JSON), the row, estimator, fold (its test files), seed and the experiment's
options. A value is an `.npz` of arrays written atomically (`io.atomic`), named by its key in the
store's folder: `default_location()`, beside the compilation cache (`$XDG_CACHE_HOME/g2r_jax/
downstream`, or `$G2R_JAX_DOWNSTREAM_CACHE`). The store keeps at most `cap_bytes`: after a write,
the least recently used files (by modification time, refreshed on each read) are removed until it
fits. A file that cannot be read is treated as missing (and removed); a store that cannot be
written is used read-only, with one note. `g2r-downstream --no-cache` (`DownstreamCache(None)`)
turns it off.
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
from pathlib import Path

import numpy as np

__all__ = ["DownstreamCache", "default_location", "code_digest", "key_of", "profile_text", "LOCATION_VARIABLE", "DEFAULT_CAP"]

LOCATION_VARIABLE = "G2R_JAX_DOWNSTREAM_CACHE"
DEFAULT_CAP = 512 * 2 ** 20       # bytes: a check's estimates take kilobytes, an ISP's examples more


def default_location() -> Path:
    """`$G2R_JAX_DOWNSTREAM_CACHE`, else `$XDG_CACHE_HOME/g2r_jax/downstream`, else
    `~/.cache/g2r_jax/downstream` (beside the compilation cache's `jax`)."""
    if os.environ.get(LOCATION_VARIABLE):
        return Path(os.environ[LOCATION_VARIABLE]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "g2r_jax" / "downstream"


@functools.lru_cache(maxsize=1)
def code_digest() -> str:
    """SHA-256 of every Python source file of the package (paths and contents, sorted)."""
    root = Path(__file__).resolve().parents[2]   # the g2r_jax package
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _update(digest, part) -> None:
    """Feed one part of a key: arrays by dtype, shape and bytes; sequences element by element;
    anything else by its repr."""
    if isinstance(part, np.ndarray) or (hasattr(part, "dtype") and hasattr(part, "shape")):
        array = np.ascontiguousarray(np.asarray(part))
        digest.update(f"array {array.dtype.str} {array.shape}".encode())
        digest.update(array.tobytes())
    elif isinstance(part, (list, tuple)):
        digest.update(f"seq {len(part)}".encode())
        for item in part:
            _update(digest, item)
    else:
        digest.update(f"{type(part).__name__} {part!r}".encode())


def profile_text(profile) -> str:
    """A profile as a key part: its JSON (`profile.schema.profile_to_dict`), keys sorted."""
    import json

    from g2r_jax.profile.schema import profile_to_dict

    return json.dumps(profile_to_dict(profile), sort_keys=True, default=str)


def key_of(*parts) -> str:
    """A hex key of `parts` (arrays, sequences of them, strings, numbers)."""
    digest = hashlib.sha256()
    for part in parts:
        _update(digest, part)
    return digest.hexdigest()


class DownstreamCache:
    """The store (module docstring). `DownstreamCache(None)` stores nothing; `hits` and `misses`
    count this run's look-ups; `notes` say what went wrong with the folder, once."""

    def __init__(self, folder=None, *, cap_bytes: int = DEFAULT_CAP):
        self.folder = None if folder is None else Path(folder)
        self.cap_bytes, self.hits, self.misses, self.notes = int(cap_bytes), 0, 0, []

    @property
    def enabled(self) -> bool:
        return self.folder is not None

    def _path(self, key: str) -> Path:
        return self.folder / f"{key}.npz"

    def get(self, key: str):
        """The arrays stored under `key` (a dict), or None."""
        if not self.enabled:
            return None
        path = self._path(key)
        try:
            with np.load(path, allow_pickle=False) as stored:
                value = {name: stored[name] for name in stored.files}
            os.utime(path)
        except FileNotFoundError:
            self.misses += 1
            return None
        except (OSError, ValueError, EOFError):        # a damaged file: as if missing
            path.unlink(missing_ok=True)
            self.misses += 1
            return None
        self.hits += 1
        return value

    def put(self, key: str, arrays: dict) -> None:
        """Store `arrays` under `key` (atomically), then keep the store under its cap."""
        if not self.enabled:
            return
        from g2r_jax.io.atomic import atomic_write_bytes

        buffer = io.BytesIO()
        np.savez(buffer, **{name: np.asarray(value) for name, value in arrays.items()})
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            atomic_write_bytes(self._path(key), buffer.getvalue())
        except Exception as error:  # noqa: BLE001 - a store that cannot be written is read-only
            if not self.notes:
                self.notes.append(f"the downstream cache {self.folder} cannot be written ({error}); nothing stored")
            return
        self.trim()

    def trim(self) -> None:
        """Remove the least recently used entries until the store holds at most `cap_bytes`."""
        entries = []
        for path in self.folder.glob("*.npz"):
            try:
                status = path.stat()
            except OSError:
                continue
            entries.append((status.st_mtime, status.st_size, path))
        total = sum(size for _, size, _ in entries)
        for _, size, path in sorted(entries):
            if total <= self.cap_bytes:
                break
            path.unlink(missing_ok=True)
            total -= size

    def summary(self) -> str:
        """One line: what this run reused."""
        if not self.enabled:
            return "downstream cache off: every training ran"
        return (f"reused {self.hits} of {self.hits + self.misses} trainings from the downstream cache "
                f"({self.folder})")
