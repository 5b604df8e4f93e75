"""The output folder of a conversion, kept like a small database.

- One writer at a time: an exclusive lock on '<folder>/.g2r.lock' (`fcntl.flock`, released by the
  system when the process ends, even killed); a second run is refused with one line.
- No stale temporaries: '.<name>.*.tmp' files left by a killed run are removed (and counted)
  when the folder is opened, since no other writer holds the lock.
- A manifest that lists exactly the DNGs there: 'manifest.jsonl' holds one JSON record per
  output; each new file's record is appended (one `write` with O_APPEND, fsync'ed) right after the
  file is renamed into place, under the commit lock of `g2r_jax.io.atomic`, so an interruption
  leaves both or neither. On opening, the manifest is rebuilt from what is there: records whose
  file is gone, unreadable lines (a killed append) and all but the last record of an output are
  dropped. DNGs that have no record (neither as an output nor as a file of its `pair`:
  `g2r-convert --pairs`) are reported (`OutputFolder.unlisted`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from g2r_jax.io.atomic import COMMIT_LOCK, OutputError, atomic_write_bytes, output_problem, remove_temporaries

__all__ = ["OutputFolder", "check_output_folder", "open_folders", "manifest_bytes", "MANIFEST_NAME", "LOCK_NAME"]

MANIFEST_NAME = "manifest.jsonl"
LOCK_NAME = ".g2r.lock"
_OPEN: list = []


def open_folders() -> list:
    """The output folders open in this process (for the line of an interrupted command)."""
    return list(_OPEN)


def check_output_folder(path) -> Path:
    """Create the folder if missing and check that files can be created in it; `OutputError`
    naming the folder otherwise. Cheap (no JAX): commands call it before any work."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(path, "exists and is not a folder (give a folder for the outputs)")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputError(path, f"cannot create the output folder: {output_problem(error)}") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise OutputError(path, "the output folder is not writable")
    return path



def manifest_bytes(records) -> bytes:
    """The manifest's content: one JSON record a line."""
    return "".join(json.dumps(r) + "\n" for r in records).encode()

class OutputFolder:
    """An opened output folder: locked, cleaned, its manifest rebuilt.

    **Arguments:** `path`: the folder (created if missing); `command`: the name shown to a
    second writer.

    Use as a context manager; `append(record)` adds one record after its file is in place,
    `rewrite(records)` replaces the manifest, `close()` releases the lock.
    """

    def __init__(self, path, command: str = "g2r-convert"):
        self.path = check_output_folder(path)
        self.manifest = self.path / MANIFEST_NAME
        self.written = 0
        self._lock_handle = None
        self._lock(command)
        self.removed_temporaries = remove_temporaries(self.path.rglob(".*"))
        self.records = self._rebuild()
        listed = {self.key(r) for r in self.records} | {Path(str(path)).as_posix() for r in self.records
                                                        for path in (r.get("pair") or {}).values()}
        self.unlisted = sorted(name for name in self._relative("*.dng") if name not in listed)
        _OPEN.append(self)

    def _lock(self, command: str) -> None:
        lock_path = self.path / LOCK_NAME
        try:
            handle = open(lock_path, "a+")
        except OSError as error:
            raise OutputError(self.path, f"cannot write into the output folder: {output_problem(error)}") from None
        try:
            import fcntl
        except ImportError:        # no advisory locks on this system: one writer is assumed
            self._lock_handle = handle
            return
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.seek(0)
            owner = handle.read(64).strip()
            handle.close()
            raise OutputError(self.path, f"another {command} is writing into this folder"
                                         f"{f' (process {owner})' if owner.isdigit() else ''}; "
                                         "wait for it to finish or choose another folder") from None
        handle.seek(0)
        handle.truncate()
        handle.write(str(os.getpid()))
        handle.flush()
        self._lock_handle = handle

    def _relative(self, pattern: str) -> list:
        """Files matching `pattern` in the folder and its sub-folders, as relative POSIX paths."""
        return [p.relative_to(self.path).as_posix() for p in self.path.rglob(pattern) if p.is_file()]

    def key(self, record) -> str | None:
        """A record's output as a path relative to the folder; None when that file is not there.
        Records name it relative to the folder, or (older runs) as given on the command line."""
        output = Path(str(record["output"]))
        for candidate in ((self.path / output,) if not output.is_absolute() else ()) + (output,):
            if candidate.is_file():
                relative = Path(os.path.relpath(candidate.resolve(), self.path.resolve()))
                return None if relative.parts[:1] == ("..",) else relative.as_posix()
        return None

    def _rebuild(self) -> list:
        if not self.manifest.exists():
            return []
        try:
            lines = self.manifest.read_bytes().splitlines()
        except OSError as error:
            raise OutputError(self.manifest, f"cannot read the manifest: {output_problem(error)}") from None
        records = []
        for line in lines:
            try:
                record = json.loads(line)
                Path(str(record["output"]))
            except (ValueError, TypeError, KeyError):
                continue                        # a line cut by a killed run
            records.append(record)
        self.records = records
        self.compact()
        return self.records

    def compact(self) -> None:
        """Rewrite the manifest with the last record of each output whose file is there (a
        re-run appends a newer record for a file it replaces)."""
        latest = {}
        for record in self.records:
            key = self.key(record)
            if key is not None:
                latest.pop(key, None)
                latest[key] = record
        self.rewrite(list(latest.values()))

    def rewrite(self, records) -> None:
        """Replace the manifest by `records` (one JSON line each), atomically; no file when empty."""
        self.records = list(records)
        if not self.records:
            with COMMIT_LOCK:
                self.manifest.unlink(missing_ok=True)
            return
        atomic_write_bytes(self.manifest, manifest_bytes(self.records))

    def append(self, record: dict, output: Path) -> None:
        """Append one record; called under the commit lock right after `output` is renamed into
        place. If the line cannot be written, `output` is removed (the manifest stays exact)
        and `OutputError` names the manifest."""
        line = (json.dumps(record) + "\n").encode()
        try:
            descriptor = os.open(self.manifest, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        except OSError as error:
            Path(output).unlink(missing_ok=True)
            raise OutputError(self.manifest, f"cannot write: {output_problem(error)}") from None
        try:
            size = os.fstat(descriptor).st_size
            try:
                if os.write(descriptor, line) != len(line):
                    raise OSError(28, "short write")
                os.fsync(descriptor)
            except OSError as error:
                os.ftruncate(descriptor, size)
                Path(output).unlink(missing_ok=True)
                raise OutputError(self.manifest, f"cannot write: {output_problem(error)}") from None
        finally:
            os.close(descriptor)
        self.records.append(record)
        self.written += 1

    def close(self) -> None:
        if self in _OPEN:
            _OPEN.remove(self)
        if self._lock_handle is not None:
            self._lock_handle.close()     # releases the lock
            self._lock_handle = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
