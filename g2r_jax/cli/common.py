"""What every command shares: one-line messages of our own, no tracebacks unless --debug.

A command's user sees only lines that start with the command's name. Python warnings raised by
g2r_jax (UserWarning) become one `name: warning: ...` line; other warnings (numpy's
RuntimeWarnings included, wherever they are triggered) and log records of libraries (tifffile,
rawpy, colour-science, JAX and its solvers) are not shown unless `--debug` is given: the reading
code turns what matters in them into its own messages naming the file (`g2r_jax.io.dng_read`).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
import warnings
from pathlib import Path

from g2r_jax.io.text import MAX_MESSAGE, MAX_SHOWN, one_line, shown  # noqa: F401  (the commands' one vocabulary)

_PACKAGE_DIR = str(Path(__file__).resolve().parents[1])
# Text that betrays a message from the numerical libraries rather than from g2r_jax.
_LIBRARY_MARKERS = ("equinox", "optimistix", "lineax", "xlaruntimeerror", "jaxlib", "jax._src", "cpucallback",
                    "callback error", "traceback", "filter_jit", "nonlinear solver")


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
            return one_line(f"{shown(error.path)}: numerical failure while using this file's values "
                            f"({type(error.__cause__ or error).__name__}; --debug shows details)")
        return one_line(f"{shown(error.path)}: {error.problem}")
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


def run_command(name: str, body, argv, parser, check=None) -> int:
    """Parse `argv`, run `body(args)`; print 'name: error: message' on failure (exit 2),
    or the traceback too with --debug. `body` returns the exit code.

    No arguments at all print the command's help (exit 2). `check(args)` returns the first problem
    of the arguments that needs no heavy import (a value out of range, an output path that cannot
    be written), reported like argparse's own errors before anything is imported or computed.
    Without `--no-compile-cache` JAX's persistent compilation cache is on
    (`g2r_jax.runtime.compile_cache`). XLA's deterministic GPU operations are requested
    (`g2r_jax.runtime.deterministic`).

    SIGINT and SIGTERM stop the command cleanly from its first line on (`StopOnSignal`).
    """
    from g2r_jax.cli.interruption import StopOnSignal

    with StopOnSignal(name):
        return _run_command(name, body, argv, parser, check)


def _run_command(name: str, body, argv, parser, check=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv:
        parser.print_help(sys.stderr)
        return 2
    try:   # argparse exits on --help and on errors: the code is returned like any other
        args = parser.parse_args(argv)
    except SystemExit as done:
        return done.code if isinstance(done.code, int) else (0 if done.code is None else 2)
    problem = check(args) if check else None
    if problem:   # a value, not the syntax: one line, like every other error of ours
        print(f"{name}: error: {one_line(problem)}", file=sys.stderr)
        return 2
    debug = bool(getattr(args, "debug", False))
    if not debug:   # XLA's own C++ log lines (e.g. its slow-compilation alarm on a loaded machine) are not ours;
        os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")   # read when jaxlib loads, i.e. in `body`
    from g2r_jax.runtime.deterministic import request_deterministic_gpu_ops

    request_deterministic_gpu_ops()
    if not args.no_compile_cache:
        from g2r_jax.runtime.compile_cache import enable

        enable(program=name)
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


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """`--help` with each option's default where it has one worth showing, and the epilog (the
    examples) laid out as written."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (action.option_strings and "%(default)" not in text and default is not None
                and not isinstance(default, bool) and default is not argparse.SUPPRESS):
            text += " (default: %(default)s)"
        return text


def command_parser(prog: str, description: str, examples: str, usage: str | None = None):
    """A command's parser: defaults in the help, `examples` (lines of shell) as its epilog."""
    import textwrap

    return argparse.ArgumentParser(prog=prog, description=textwrap.fill(" ".join(description.split()), 88),
                                   usage=usage, formatter_class=HelpFormatter, epilog="examples:\n" + examples)


def required_group(parser):
    """An argument group titled 'required', listed in --help before the optional ones."""
    group = parser.add_argument_group("required")
    parser._action_groups.remove(group)   # argparse lists groups in creation order
    parser._action_groups.insert(1, group)
    return group


def add_common_flags(parser) -> None:
    """The flags every command has: --quiet (--no-progress is kept as a hidden alias), --debug,
    --no-compile-cache."""
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bar, notes or hints; errors and the final summary still print")
    parser.add_argument("--no-progress", dest="quiet", action="store_true", help=argparse.SUPPRESS)
    add_debug_flag(parser)
    parser.add_argument("--no-compile-cache", action="store_true",
                        help="do not use the on-disk compilation cache (default location "
                             "~/.cache/g2r_jax/jax, or $G2R_JAX_CACHE_DIR)")


def output_file_problem(option: str, path: Path, *, create_folder: bool = False) -> str | None:
    """Why the file `path` (given as `option`) could not be written, found before any work; None
    when it can. `create_folder`: a missing folder will be created (else it must exist)."""
    if path.is_dir():
        return f"{option} {path}: is a folder; give the file to write (e.g. {path / ('name' + (path.suffix or '.json'))})"
    folder = path.parent
    if create_folder:
        return output_folder_problem(option, folder, given=path)
    if not folder.exists():
        return f"{option} {path}: the folder {folder} does not exist (create it first)"
    if not folder.is_dir():
        return f"{option} {path}: {folder} is a file, not a folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"{option} {path}: no permission to write in {folder}"
    return None


def output_folder_problem(option: str, path: Path, *, given: Path | None = None) -> str | None:
    """Why the folder `path` could not be created or written to; None when it can. `given`: the
    path the user typed when `path` is its folder (named in the message)."""
    given = path if given is None else given
    existing = path
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        if existing == given:
            return f"{option} {given}: is a file; a folder is needed here"
        return f"{option} {given}: {existing} is a file, not a folder"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{option} {given}: no permission to write in {existing}"
    return None
