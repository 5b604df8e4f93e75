"""Options for XLA, set through the `XLA_FLAGS` environment variable before JAX starts a backend
(XLA reads it once, then). One rule for every option g2r_jax sets: a value the user chose wins."""

from __future__ import annotations

import os
import re


def chosen(name: str) -> str | None:
    """The value of `--name=` in `XLA_FLAGS`, or None when it is not there."""
    found = re.search(rf"--{re.escape(name)}=(\S*)", os.environ.get("XLA_FLAGS", ""))
    return found.group(1) if found else None


def add_flag(name: str, value: str) -> bool:
    """Append `--name=value` to `XLA_FLAGS` unless the user already gave `name` a value; returns
    whether it was added. Call it before any JAX computation."""
    flags = os.environ.get("XLA_FLAGS", "")
    if name in flags:
        return False
    os.environ["XLA_FLAGS"] = f"{flags} --{name}={value}".strip()
    return True
