"""Keeping C libraries' own error printing (OpenEXR's core writes to file descriptor 2 directly)
away from the user: their text is captured while they run; the Python exception they raise
becomes our one-line message instead. Other text written meanwhile (our own lines from other
threads) is passed on unchanged."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading

_LOCK = threading.Lock()


@contextlib.contextmanager
def captured_native_stderr(is_library_line):
    """Redirect file descriptor 2 while the block runs; afterwards write back the captured lines for
    which `is_library_line(line)` is False. Serialised by a lock (the descriptor is process-wide)."""
    with _LOCK:
        try:
            sys.stderr.flush()
        except Exception:  # noqa: BLE001 - a closed or replaced stderr: nothing to flush
            pass
        saved = os.dup(2)
        with tempfile.TemporaryFile() as sink:
            os.dup2(sink.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
                os.close(saved)
                sink.seek(0)
                text = sink.read().decode("utf-8", "replace")
        kept = [line for line in text.splitlines(keepends=True) if line.strip() and not is_library_line(line)]
        if kept:
            os.write(2, "".join(kept).encode())
