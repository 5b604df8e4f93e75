"""Read camera spectral sensitivity functions (SSF) from the three formats in use.

- rawtoaces JSON (Academy rawtoaces-data `camera/*.json`): `spectral_data.data.main` maps
  wavelength strings to [r, g, b]; `header.manufacturer` / `header.model` name the camera.
- camspec text (Jiang, Liu, Gu, Suesstrunk, WACV 2013, `camspec_database.txt`): header lines,
  then per camera a name line and three lines (R, G, B) of 33 values, 400-720 nm at 10 nm.
- CSV with a header `wavelength,r,g,b` (nm, any spacing, ascending).

Every result is resampled to the spectral model's grid (`g2r_jax.io.spectral_grid.WAVELENGTHS`) and
normalised so that the green channel's peak is 1. Bad input raises `DngError(path, problem)`.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from g2r_jax.io.text import shown
from g2r_jax.io.dng_info import DngError

CAMSPEC_WAVELENGTHS = np.arange(400.0, 721.0, 10.0)
MAX_CAMERA = 80   # characters of a camera name read from the file (control characters shown as escapes)


@dataclass(frozen=True)
class Sensitivities:
    """One camera's SSF on the spectral grid, (81, 3) columns R, G, B; `source` says where from."""

    camera: str
    values: np.ndarray
    source: str


MAX_VALUE = 1e12          # relative or absolute sensitivities stay far below; beyond, resampling overflows


def normalise(values) -> np.ndarray:
    values = np.clip(np.asarray(values, np.float64), 0.0, None)
    return values / values[:, 1].max()


def _check(path, wavelengths, values) -> tuple[np.ndarray, np.ndarray]:
    wavelengths = np.asarray(wavelengths, np.float64)
    values = np.asarray(values, np.float64)
    if values.ndim != 2 or values.shape[1] != 3 or len(wavelengths) != len(values) or len(values) < 4:
        raise DngError(path, "expected at least 4 wavelengths with three values (r, g, b) each")
    finite = np.isfinite(values).all(1) & np.isfinite(wavelengths)
    if not finite.all():
        raise DngError(path, f"the row at {wavelengths[~finite][0]:g} nm holds NaN or infinity")
    if np.abs(values).max() > MAX_VALUE:
        raise DngError(path, f"values beyond {MAX_VALUE:g}: not a sensitivity curve (largest {np.abs(values).max():.3g})")
    if np.any(np.diff(wavelengths) <= 0):
        raise DngError(path, "wavelengths must be strictly ascending")
    if wavelengths[0] > 420 or wavelengths[-1] < 680:
        raise DngError(path, f"wavelengths {wavelengths[0]:g}-{wavelengths[-1]:g} nm do not cover 420-680 nm")
    if np.any(values.max(0) <= 0):
        raise DngError(path, "a channel is zero everywhere")
    return wavelengths, values


def _on_grid(path, wavelengths, values) -> np.ndarray:
    from g2r_jax.io.spectral_grid import resample

    wavelengths, values = _check(path, wavelengths, values)
    return normalise(resample(wavelengths, values))


def _field(path, document, *keys) -> dict:
    """The object at `keys` in a JSON document; `DngError` naming the first missing or wrong field."""
    value = document
    for depth, key in enumerate(keys):
        if not isinstance(value, dict) or key not in value:
            where = ".".join(keys[:depth]) or "the top level"
            raise DngError(path, f"not a rawtoaces camera JSON: {where} has no object field '{key}'")
        value = value[key]
    if not isinstance(value, dict):
        raise DngError(path, f"field {'.'.join(keys)} must be an object")
    return value


def _short_text(value, limit: int = 40) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_rawtoaces_json(path) -> Sensitivities:
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as error:
        raise DngError(path, f"cannot read ({type(error).__name__})") from None
    except (json.JSONDecodeError, RecursionError) as error:
        where = f"line {error.lineno}, column {error.colno}: {error.msg}" if isinstance(error, json.JSONDecodeError) \
            else "nested too deeply"
        raise DngError(path, f"not valid JSON ({where})") from None
    table = _field(path, document, "spectral_data", "data", "main")
    header = document.get("header", {})
    if not isinstance(header, dict):
        raise DngError(path, "field header must be an object")
    rows = []
    for key, value in table.items():
        try:
            wavelength = float(key)
        except ValueError:
            raise DngError(path, f"spectral_data.data.main: key {_short_text(key)} is not a wavelength in nm") from None
        if not (isinstance(value, list) and len(value) == 3
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
            raise DngError(path, f"spectral_data.data.main[{_short_text(key)}]: expected three numbers (r, g, b), "
                                 f"got {_short_text(value)}")
        rows.append((wavelength, value))
    rows.sort(key=lambda row: row[0])
    names = [header.get(field, "") for field in ("manufacturer", "model")]
    camera = shown(" ".join(str(n) for n in names if isinstance(n, str) and n).strip(), MAX_CAMERA) or path.stem
    values = _on_grid(path, [w for w, _ in rows], [v for _, v in rows])
    return Sensitivities(camera, values, f"rawtoaces JSON {path.name}")


def read_camspec(path, camera: str | None = None) -> dict[str, Sensitivities] | Sensitivities:
    """All cameras of a camspec database file, or the one named `camera` (case-insensitive)."""
    path = Path(path)
    try:
        lines = [line.strip() for line in path.read_text().splitlines() if line.strip()]
    except (OSError, UnicodeDecodeError) as error:
        raise DngError(path, f"cannot read camspec file ({error})") from None

    def numbers(line):
        try:
            return np.array([float(x) for x in line.replace(",", " ").split()])
        except ValueError:
            return None

    cameras = {}
    index = 0
    while index < len(lines):
        rows = [numbers(l) for l in lines[index + 1:index + 4]]
        if numbers(lines[index]) is None and len(rows) == 3 and all(r is not None and len(r) == 33 for r in rows):
            name = lines[index]
            cameras[name] = Sensitivities(shown(name, MAX_CAMERA), _on_grid(path, CAMSPEC_WAVELENGTHS,
                                                                             np.stack(rows, 1)),
                                          f"camspec {path.name}: {shown(name, MAX_CAMERA)}")
            index += 4
        else:
            index += 1
    if not cameras:
        raise DngError(path, "no camera found (expected a name line, then three lines of 33 values)")
    if camera is None:
        return cameras
    wanted = camera.lower().replace(" ", "")
    for name, sensitivities in cameras.items():
        if name.lower().replace(" ", "") == wanted:
            return sensitivities
    raise DngError(path, f"camera {camera!r} not in the file (it has {len(cameras)} cameras)")


def read_csv(path) -> Sensitivities:
    path = Path(path)
    try:
        with open(path, newline="") as handle:
            rows = list(csv.DictReader(handle))
        if not rows or not {"wavelength", "r", "g", "b"} <= set(rows[0]):
            raise DngError(path, "expected a header with columns wavelength,r,g,b")
        table = []
        for line, row in enumerate(rows, start=2):
            try:
                table.append([float(row[column]) for column in ("wavelength", "r", "g", "b")])
            except (TypeError, ValueError):
                raise DngError(path, f"line {line}: not four numbers (wavelength, r, g, b)") from None
        table = np.array(table)
    except (OSError, UnicodeDecodeError) as error:
        raise DngError(path, f"cannot read sensitivity CSV ({type(error).__name__})") from None
    return Sensitivities(path.stem, _on_grid(path, table[:, 0], table[:, 1:]), f"CSV {path.name}")


def read_sensitivities(path, camera: str | None = None) -> Sensitivities:
    """Any of the three formats, told apart by content: JSON, camspec (needs `camera` when the
    file holds several), CSV."""
    path = Path(path)
    try:
        head = path.read_text()[:4096].lstrip()
    except FileNotFoundError:
        raise DngError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise DngError(path, f"cannot read ({error})") from None
    if head[:1] in ('{', '[', '"'):
        return read_rawtoaces_json(path)
    if head.lower().startswith("wavelength"):
        return read_csv(path)
    cameras = read_camspec(path)
    if camera is not None:
        return read_camspec(path, camera)
    if len(cameras) == 1:
        return next(iter(cameras.values()))
    raise DngError(path, f"a camspec file with {len(cameras)} cameras: name one (e.g. {next(iter(cameras))!r})")
