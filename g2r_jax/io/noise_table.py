"""Reading a noise calibration table (`g2r-fit-profile --noise-table`), checked row by row.

Format (CSV with a header, like ../shared/data/noise/): `iso,cfa_channel_index,beta1_shot,beta2_read`,
one row per ISO and CFA position 0..3, in DN of the raw data including the black level: the
variance of a pixel of mean x is `beta1_shot * x + beta2_read`. The values must fit the camera:
in normalised units (range = white - black) shot = beta1 / range and read = (beta1 * black +
beta2) / range^2 (`g2r_jax.profile.schema.noise_from_table`) must lie in (0, 1] and [0, 1]; a
table in other units (normalised already, or of another bit depth) is refused here, naming the
table, its line and field, instead of failing later for every DNG.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from g2r_jax.io.dng_info import DngError

__all__ = ["read_noise_table_rows", "COLUMNS"]

COLUMNS = ("iso", "cfa_channel_index", "beta1_shot", "beta2_read")


def _number(path, line: int, row: dict, column: str) -> float:
    text = row.get(column)
    try:
        value = float(text)
    except (TypeError, ValueError):
        shown = repr(text[:20] + ("..." if len(text) > 20 else "")) if isinstance(text, str) else "nothing"
        raise DngError(path, f"line {line}, {column}: {shown} is not a number") from None
    if not math.isfinite(value):
        raise DngError(path, f"line {line}, {column}: must be finite, got {value}")
    return value


def read_noise_table_rows(path, black_level, white_level) -> tuple:
    """The checked rows of a noise table: (isos (K,), beta1 (K, 4), beta2 (K, 4)).

    **Arguments:** `path`: the CSV; `black_level`: (4,) per CFA position; `white_level`: the
    camera's white level (both in DN, from the calibration DNGs).

    **Returns:** ISOs in ascending order and the two coefficients per ISO and CFA position.
    Raises `DngError(path, "line N, field: problem")` for any bad row, a missing CFA position,
    or values that do not fit the camera's range (wrong units).
    """
    path = Path(path)
    try:
        with open(path, newline="") as handle:
            reader = csv.DictReader(handle)
            if reader.fieldnames is None or not set(COLUMNS) <= set(reader.fieldnames):
                raise DngError(path, f"line 1: expected a header with columns {','.join(COLUMNS)}")
            rows = [(reader.line_num, row) for row in reader]
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise DngError(path, f"cannot read the noise table ({type(error).__name__})") from None
    if not rows:
        raise DngError(path, "no rows after the header")
    table, lines = {}, {}
    for line, row in rows:
        iso = _number(path, line, row, "iso")
        position = _number(path, line, row, "cfa_channel_index")
        if iso <= 0:
            raise DngError(path, f"line {line}, iso: must be positive, got {iso:g}")
        if position not in (0, 1, 2, 3):
            raise DngError(path, f"line {line}, cfa_channel_index: must be 0, 1, 2 or 3, got {position:g}")
        if int(position) in table.get(iso, {}):
            raise DngError(path, f"line {line}: a second row for ISO {iso:g}, CFA position {int(position)}")
        beta1, beta2 = _number(path, line, row, "beta1_shot"), _number(path, line, row, "beta2_read")
        table.setdefault(iso, {})[int(position)] = (beta1, beta2)
        lines[(iso, int(position))] = line
    isos = sorted(table)
    for iso in isos:
        missing = sorted({0, 1, 2, 3} - set(table[iso]))
        if missing:
            raise DngError(path, f"ISO {iso:g} has no row for CFA position(s) {', '.join(map(str, missing))}")
    beta1 = np.array([[table[i][p][0] for p in range(4)] for i in isos])
    beta2 = np.array([[table[i][p][1] for p in range(4)] for i in isos])
    black = np.resize(np.asarray(black_level, np.float64), 4)
    span = float(white_level) - black
    with np.errstate(over="ignore", invalid="ignore"):      # huge values become inf and are refused below
        shot = beta1 / span
        read = (beta1 * black + beta2) / span**2
    for name, values, low_open in (("beta1_shot", shot, True), ("beta2_read", read, False)):
        bad = (values <= 0) if low_open else (values < 0)
        bad |= values > 1
        if bad.any():
            k, p = map(int, np.argwhere(bad)[0])
            what = "shot" if name == "beta1_shot" else "read"
            raise DngError(path, f"line {lines[(isos[k], p)]}, {name}: the normalised {what} noise is "
                                 f"{values[k, p]:.3g}, outside {'(0, 1]' if low_open else '[0, 1]'} for this camera "
                                 f"(black {black[p]:g}, white {float(white_level):g}); the table must be in DN of "
                                 "its raw data (variance = beta1_shot * x + beta2_read)")
    return np.asarray(isos, np.float64), beta1, beta2
