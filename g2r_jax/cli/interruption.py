"""A clean stop on SIGINT (Ctrl-C) and SIGTERM at any moment, compilation included.

Python delivers a signal to its handler only when the main thread next runs Python code, which
can be many seconds later while XLA compiles, and a KeyboardInterrupt raised inside a library
callback is swallowed, or leaves the interpreter to shut down under running XLA threads (a
segmentation fault). So the handlers here do nothing themselves: the C-level handler writes the
signal's number to a socket (`signal.set_wakeup_fd`) and a watcher thread, woken at once, stops
the process: it takes the commit lock of `g2r_jax.io.atomic` (so no output is half renamed and
every manifest line matches a file), removes the temporaries being written, prints one line and
ends the process with status 130 through `os._exit`, which runs no interpreter shutdown.
"""

from __future__ import annotations

import os
import signal
import socket
import sys
import threading

from g2r_jax.io.text import shown
from g2r_jax.io import atomic
from g2r_jax.io.output_folder import open_folders

__all__ = ["StopOnSignal", "INTERRUPTED_STATUS"]

INTERRUPTED_STATUS = 130
LOCK_WAIT_SECONDS = 10.0      # an output being renamed finishes in milliseconds; a stuck disk does not


class StopOnSignal:
    """Context manager of a command's run: SIGINT and SIGTERM stop the process cleanly.

    **Arguments:** `name`: the command's name, which starts its line (followed by what the
    open output folders (`g2r_jax.io.output_folder`) hold).

    Outside the main thread (where signal handlers cannot be set) it does nothing.
    """

    def __init__(self, name: str):
        self.name = name
        self._previous, self._sockets, self._wakeup = {}, None, None

    def install(self) -> "StopOnSignal":
        """Install the handlers now (also done by entering the context; once only)."""
        if self._sockets is not None or threading.current_thread() is not threading.main_thread():
            return self
        reader, writer = socket.socketpair()
        writer.setblocking(False)
        self._sockets = (reader, writer)
        self._wakeup = signal.set_wakeup_fd(writer.fileno(), warn_on_full_buffer=False)
        for number in (signal.SIGINT, signal.SIGTERM):
            self._previous[number] = signal.signal(number, _ignore)
        threading.Thread(target=self._watch, args=(reader,), name="g2r-stop-on-signal", daemon=True).start()
        return self

    def __enter__(self):
        return self.install()

    def __exit__(self, *exc):
        if self._sockets is None:
            return False
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        signal.set_wakeup_fd(self._wakeup if self._wakeup is not None else -1)
        reader, writer = self._sockets
        self._sockets = None
        try:
            reader.shutdown(socket.SHUT_RDWR)      # wakes the watcher, which closes it
        except OSError:
            pass
        writer.close()
        return False

    def _watch(self, reader):
        """Wait for SIGINT or SIGTERM. The wakeup fd receives the number of every signal that has a
        Python-level handler (a caller's SIGALRM or SIGUSR1 too): those are passed on to the wakeup
        fd that was there before, if any, and do not stop the command."""
        while True:
            try:
                data = reader.recv(64)
            except OSError:
                data = b""
            if not data or self._sockets is None:
                break
            stop = next((number for number in data if number in (signal.SIGINT, signal.SIGTERM)), None)
            if stop is not None:
                self.stop_now(stop)
            if self._wakeup is not None and self._wakeup >= 0:
                try:
                    os.write(self._wakeup, data)
                except OSError:
                    pass
        reader.close()                        # the context was left: the watcher ends

    def stop_now(self, number: int) -> None:
        """Remove the temporaries, print one line, exit with status 130 (no interpreter shutdown)."""
        locked = atomic.COMMIT_LOCK.acquire(timeout=LOCK_WAIT_SECONDS)
        removed = 0
        for temporary in list(atomic.LIVE_TEMPORARIES):
            try:
                os.unlink(temporary)
                removed += 1
            except OSError:
                pass
        what = "interrupted" if number == signal.SIGINT else "stopped (SIGTERM)"
        done = ""
        try:
            done = "".join(f"; {folder.written} file(s) written to {shown(folder.path)}, listed in its "
                           f"{folder.manifest.name}" for folder in open_folders())
        except Exception:  # noqa: BLE001 - the line must go out whatever the state
            done = ""
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001
                pass
        os.write(2, f"\n{self.name}: {what}{done}\n".encode("utf-8", "replace"))
        del locked
        os._exit(INTERRUPTED_STATUS)


def _ignore(number, frame):
    """The Python-level handler: nothing; the watcher thread has been woken by the wakeup fd."""
