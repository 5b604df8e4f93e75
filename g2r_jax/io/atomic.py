"""Atomic file writing: a temporary sibling, fsync, then rename, so no partial output is left.

Every temporary file being written is registered (`LIVE_TEMPORARIES`), so that a command stopped
by a signal removes them before it exits (`g2r_jax.cli.interruption`), and a temporary is created
and a finished file renamed under one lock (`COMMIT_LOCK`), which the stopping command takes
first: an output is either complete under its name or absent. Failures are reported with the
final file's name and a sentence of ours (`OutputError`), never the temporary's name or errno text.
"""

from __future__ import annotations

import errno
import os
import tempfile
import threading
from pathlib import Path

from g2r_jax.io.dng_info import DngError

__all__ = ["OutputError", "atomic_write_bytes", "output_problem", "LIVE_TEMPORARIES", "COMMIT_LOCK",
           "TEMPORARY_SUFFIX", "is_temporary_name"]

TEMPORARY_SUFFIX = ".tmp"
COMMIT_LOCK = threading.RLock()      # held while a temporary is created or renamed into place
LIVE_TEMPORARIES: set = set()

_PROBLEMS = {
    errno.ENOSPC: "no space left on the disk",
    errno.EDQUOT: "disk quota exceeded",
    errno.EROFS: "the folder is on a read-only file system",
    errno.EACCES: "permission denied (the folder is not writable)",
    errno.EPERM: "permission denied (the folder is not writable)",
    errno.ENOENT: "the folder does not exist (or was removed during the run)",
    errno.ENOTDIR: "a part of the path is a file, not a folder",
    errno.EISDIR: "a folder is in the way (the path names a folder)",
    errno.ENAMETOOLONG: "the file name is too long for this file system",
    errno.EFBIG: "the file is too large for this file system",
    errno.EIO: "input/output error on the disk",
}


class OutputError(DngError):
    """An output could not be written; `path` is the output's own name, `problem` our sentence.
    Raised for faults of the output folder (disk full, permissions), which stop a batch."""


def output_problem(error: BaseException) -> str:
    """Our sentence for an OS error met while writing (no errno number, no temporary name)."""
    if isinstance(error, OSError) and error.errno in _PROBLEMS:
        return _PROBLEMS[error.errno]
    if isinstance(error, OSError):
        return f"the system refused the write ({(error.strerror or type(error).__name__).lower()})"
    return f"{type(error).__name__}"


def is_temporary_name(name: str) -> bool:
    """True for a name `atomic_write_bytes` gives its temporaries: '.<name>.<random>.tmp'."""
    return name.startswith(".") and name.endswith(TEMPORARY_SUFFIX) and name.count(".") >= 3


def remove_temporaries(entries) -> int:
    """Delete those of `entries` (paths) that are temporaries of `atomic_write_bytes` left by a
    killed run (SIGKILL: a run stopped by SIGINT or SIGTERM removes its own); their count.
    Entries that vanish or cannot be deleted are skipped."""
    removed = 0
    for entry in entries:
        if is_temporary_name(entry.name) and entry.is_file():
            try:
                entry.unlink()
                removed += 1
            except OSError:
                pass
    return removed


def atomic_write_bytes(path, data, *, after_rename=None) -> None:
    """Write `data` to `path` atomically.

    **Arguments:** `path`: the output file; `data`: bytes, or a callable writing to a binary
    handle (e.g. `lambda handle: figure.savefig(handle, format="png")`); `after_rename`: called
    under `COMMIT_LOCK` right after the rename (a manifest line for this file), so that an
    interruption leaves both or neither.

    A uniquely named '.<name>.*.tmp' sibling is written, fsync'ed and renamed onto `path`; on
    any failure it is removed, `path` is untouched and `OutputError(path, sentence)` is raised
    for OS errors.
    """
    path = Path(path)
    try:
        with COMMIT_LOCK:
            descriptor, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX,
                                                     dir=path.parent)
            LIVE_TEMPORARIES.add(temporary)
    except OSError as error:
        raise OutputError(path, f"cannot write: {output_problem(error)}") from None
    try:
        with os.fdopen(descriptor, "wb") as handle:
            if callable(data):
                data(handle)
            else:
                handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(temporary, 0o644)
        with COMMIT_LOCK:
            os.replace(temporary, path)
            LIVE_TEMPORARIES.discard(temporary)
            if after_rename is not None:
                after_rename()
    except OSError as error:
        raise OutputError(path, f"cannot write: {output_problem(error)}") from None
    finally:
        with COMMIT_LOCK:
            if temporary in LIVE_TEMPORARIES:
                LIVE_TEMPORARIES.discard(temporary)
                Path(temporary).unlink(missing_ok=True)
