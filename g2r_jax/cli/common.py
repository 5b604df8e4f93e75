"""What every command shares: one-line messages of our own, no tracebacks unless --debug.

A command's user sees only lines that start with the command's name. Python warnings raised by
g2r_jax (UserWarning) become one `name: warning: ...` line; other warnings (numpy's
RuntimeWarnings included, wherever they are triggered) and log records of libraries (tifffile,
rawpy, colour-science, JAX and its solvers) are not shown unless `--debug` is given: the reading
code turns what matters in them into its own messages naming the file (`g2r_jax.io.dng_read`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import warnings
from pathlib import Path

MAX_MESSAGE = 300
_PACKAGE_DIR = str(Path(__file__).resolve().parents[1])
# Text that betrays a message from the numerical libraries rather than from g2r_jax.
_LIBRARY_MARKERS = ("equinox", "optimistix", "lineax", "xlaruntimeerror", "jaxlib", "jax._src", "cpucallback",
                    "callback error", "traceback", "filter_jit", "nonlinear solver")


def one_line(message, limit: int = MAX_MESSAGE) -> str:
    """`message` as one short line: whitespace collapsed, at most `limit` characters."""
    text = " ".join(str(message).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def is_library_text(message) -> bool:
    """True when `message` reads like a JAX/equinox/XLA internal message (not one of ours)."""
    head = str(message).lower()
    return any(marker in head for marker in _LIBRARY_MARKERS) or str(message).count("\n") > 2


def error_message(error: BaseException) -> str:
    """The user's line for an exception: our own message shortened, or a plain sentence in place
    of a numerical library's dump (which `--debug` shows in full)."""
    from g2r_jax.io.dng_info import DngError

    if isinstance(error, DngError):
        if is_library_text(error.problem):
            return one_line(f"{error.path}: numerical failure while using this file's values "
                            f"({type(error.__cause__ or error).__name__}; --debug shows details)")
        return one_line(error)
    if is_library_text(error) or type(error).__module__.split(".")[0] in ("jax", "jaxlib", "equinox", "optimistix",
                                                                         "lineax"):
        return f"numerical failure ({type(error).__name__}; --debug shows details)"
    return one_line(error) or type(error).__name__


class _Collect(logging.Handler):
    """Keeps library log records instead of printing them (logging's last-resort handler would)."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.records = []

    def emit(self, record):
        self.records.append(record)


@contextlib.contextmanager
def quiet_libraries(name: str, debug: bool = False):
    """While a command runs: library log records are collected, not printed; Python warnings from
    g2r_jax are printed as one line each, others dropped. With `debug`, everything is shown."""
    if debug:
        logging.basicConfig(level=logging.WARNING)
        yield
        return
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")   # XLA's C++ logging
    root = logging.getLogger()
    handler = _Collect()
    root.addHandler(handler)

    def show(message, category, filename, lineno, file=None, line=None):
        if str(filename).startswith(_PACKAGE_DIR) and issubclass(category, UserWarning):   # numpy's RuntimeWarnings: no
            print(f"{name}: warning: {one_line(message)}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = show
        try:
            yield
        finally:
            root.removeHandler(handler)


def run_command(name: str, body, argv, parser) -> int:
    """Parse `argv`, run `body(args)`; print 'name: error: message' on failure (exit 2),
    or the traceback too with --debug. `body` returns the exit code. Every command gets
    `--no-compile-cache`; without it JAX's persistent compilation cache is on
    (`g2r_jax.compile_cache`). XLA's deterministic GPU operations are requested
    (`g2r_jax.deterministic`)."""
    parser.add_argument("--no-compile-cache", action="store_true",
                        help="do not use the on-disk compilation cache (default location "
                             "~/.cache/g2r_jax/jax, or $G2R_JAX_CACHE_DIR)")
    args = parser.parse_args(argv)
    from g2r_jax.runtime.deterministic import request_deterministic_gpu_ops

    request_deterministic_gpu_ops()
    if not args.no_compile_cache:
        from g2r_jax.runtime.compile_cache import enable

        enable(program=name)
    debug = bool(getattr(args, "debug", False))
    with quiet_libraries(name, debug):
        try:
            return int(body(args) or 0)
        except KeyboardInterrupt:
            print(f"{name}: interrupted", file=sys.stderr)
            return 130
        except Exception as error:  # noqa: BLE001 - the command's last line of defence
            if debug:
                raise
            print(f"{name}: error: {error_message(error)}", file=sys.stderr)
            return 2


def add_debug_flag(parser) -> None:
    parser.add_argument("--debug", action="store_true",
                        help="show full tracebacks and the libraries' own warnings and log messages")
