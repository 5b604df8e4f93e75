"""Text echoed from files and paths, made safe for one terminal line: control characters shown as
escapes, never sent; lengths cut."""

from __future__ import annotations

MAX_MESSAGE = 300
MAX_SHOWN = 160           # characters of a path or of a value read from a file, in one message


def shown(value, limit: int = MAX_SHOWN) -> str:
    """`value` (a path, a file name, text read from a file) as safe text inside one line.

    Every character that is not printable (newline, tab, ESC and the other control characters,
    undecodable bytes of a file name) is shown as a Python escape (`\\n`, `\\x1b`, `\\udcff`),
    never sent to the terminal; the result is cut to `limit` characters, ending in '...'.
    """
    text = str(value)
    escaped = "".join(char if char.isprintable() else _escape(char) for char in text[:limit])
    if len(text) > limit or len(escaped) > limit:
        escaped = escaped[: max(0, limit - 3)] + "..."
    return escaped


def _escape(char: str) -> str:
    code = ord(char)
    if char in "\n\r\t":
        return repr(char)[1:-1]
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def one_line(message, limit: int = MAX_MESSAGE) -> str:
    """`message` as one short, safe line: whitespace runs collapsed to one space, any other
    control character shown as an escape (`shown`), at most `limit` characters."""
    return shown(" ".join(str(message)[: 4 * limit].split()), limit)
