"""What every command shares: one-line errors without tracebacks unless --debug."""

from __future__ import annotations

import sys


def run_command(name: str, body, argv, parser) -> int:
    """Parse `argv`, run `body(args)`; print 'name: error: message' on failure (exit 2),
    or the traceback too with --debug. `body` returns the exit code."""
    args = parser.parse_args(argv)
    try:
        return int(body(args) or 0)
    except KeyboardInterrupt:
        print(f"{name}: interrupted", file=sys.stderr)
        return 130
    except Exception as error:  # noqa: BLE001 - the command's last line of defence
        if getattr(args, "debug", False):
            raise
        print(f"{name}: error: {error}", file=sys.stderr)
        return 2


def add_debug_flag(parser) -> None:
    parser.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
