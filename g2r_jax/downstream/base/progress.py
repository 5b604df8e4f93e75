"""What a long check is doing and how long it has left: a progress bar on stderr (tqdm) over
the trainings the check has planned, with the time left that tqdm estimates from the rate so
far, and the check's lines of text printed above the bar.

A `Progress` is a callable taking one line of text, like the plain callables the checks accept
as `progress=`; `plan` and `advance` work on either (on a plain callable they do nothing), so
every check reports to both without knowing which it was given.
"""

from __future__ import annotations

import sys
from typing import Callable, Optional


class Progress:
    """Lines of text (`say`) and, with `bar`, a tqdm bar of the planned units of work on
    `stream` (default stderr) showing elapsed and remaining time. Use as a context manager or
    call `close`."""

    def __init__(self, say: Optional[Callable[[str], None]] = None, *, bar: bool = True, stream=None,
                 unit: str = "training", desc: str = ""):
        self._say = say or (lambda line: None)
        self._stream = stream or sys.stderr
        self._bar = None
        if bar:
            from tqdm import tqdm

            self._bar = tqdm(total=0, unit=unit, desc=desc, file=self._stream, dynamic_ncols=True, leave=False,
                             bar_format="{desc} {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} trainings "
                                        "[{elapsed} elapsed, about {remaining} left] {postfix}")

    def __call__(self, line: str) -> None:
        if self._bar is not None:
            self._bar.clear()
            self._say(line)
            self._bar.refresh()
        else:
            self._say(line)

    def plan(self, units: int) -> None:
        """Add `units` of work to the total (the time left counts them)."""
        if self._bar is not None:
            self._bar.total += int(units)
            self._bar.refresh()

    def advance(self, units: int = 1, doing: str = "") -> None:
        """`units` of work done; `doing` says what comes next (shown beside the bar)."""
        if self._bar is not None:
            if doing:
                self._bar.set_postfix_str(doing, refresh=False)
            self._bar.update(int(units))

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def plan(progress, units: int) -> None:
    """`progress.plan(units)` when `progress` is a `Progress`; nothing for a plain callable or None."""
    if hasattr(progress, "plan"):
        progress.plan(units)


def advance(progress, units: int = 1, doing: str = "") -> None:
    """`progress.advance(units, doing)` when `progress` is a `Progress`; nothing otherwise."""
    if hasattr(progress, "advance"):
        progress.advance(units, doing)
