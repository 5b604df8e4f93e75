"""Read camera spectral sensitivity functions (SSF) from the three formats in use.

- rawtoaces JSON (Academy rawtoaces-data `camera/*.json`): `spectral_data.data.main` maps
  wavelength strings to [r, g, b]; `header.manufacturer` / `header.model` name the camera.
- camspec text (Jiang, Liu, Gu, Suesstrunk, WACV 2013, `camspec_database.txt`): header lines,
  then per camera a name line and three lines (R, G, B) of 33 values, 400-720 nm at 10 nm.
- CSV with a header `wavelength,r,g,b` (nm, any spacing, ascending).

Every result is resampled to the spectral model's grid (`g2r_jax.spectral.tables.WAVELENGTHS`) and
normalised so that the green channel's peak is 1. Bad input raises `DngError(path, problem)`.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from g2r_jax.io.dng_info import DngError

CAMSPEC_WAVELENGTHS = np.arange(400.0, 721.0, 10.0)


@dataclass(frozen=True)
class Sensitivities:
    """One camera's SSF on the spectral grid, (81, 3) columns R, G, B; `source` says where from."""

    camera: str
    values: np.ndarray
    source: str


def normalise(values) -> np.ndarray:
    values = np.clip(np.asarray(values, np.float64), 0.0, None)
    return values / values[:, 1].max()


def _check(path, wavelengths, values) -> tuple[np.ndarray, np.ndarray]:
    wavelengths = np.asarray(wavelengths, np.float64)
    values = np.asarray(values, np.float64)
    if values.ndim != 2 or values.shape[1] != 3 or len(wavelengths) != len(values) or len(values) < 4:
        raise DngError(path, "expected at least 4 wavelengths with three values (r, g, b) each")
    if not np.all(np.isfinite(values)) or not np.all(np.isfinite(wavelengths)):
        raise DngError(path, "contains NaN or infinity")
    if np.any(np.diff(wavelengths) <= 0):
        raise DngError(path, "wavelengths must be strictly ascending")
    if wavelengths[0] > 420 or wavelengths[-1] < 680:
        raise DngError(path, f"wavelengths {wavelengths[0]:g}-{wavelengths[-1]:g} nm do not cover 420-680 nm")
    if np.any(values.max(0) <= 0):
        raise DngError(path, "a channel is zero everywhere")
    return wavelengths, values


def _on_grid(path, wavelengths, values) -> np.ndarray:
    from g2r_jax.colour.spectral.tables import resample

    wavelengths, values = _check(path, wavelengths, values)
    return normalise(resample(wavelengths, values))


def read_rawtoaces_json(path) -> Sensitivities:
    path = Path(path)
    try:
        document = json.loads(path.read_text())
        table = document["spectral_data"]["data"]["main"]
        header = document.get("header", {})
        rows = sorted((float(k), v) for k, v in table.items())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError, ValueError) as error:
        raise DngError(path, f"not a rawtoaces camera JSON ({type(error).__name__}: {error})") from None
    camera = f"{header.get('manufacturer', '')} {header.get('model', '')}".strip() or path.stem
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
            cameras[name] = Sensitivities(name, _on_grid(path, CAMSPEC_WAVELENGTHS, np.stack(rows, 1)),
                                          f"camspec {path.name}: {name}")
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
        table = np.array([[float(r["wavelength"]), float(r["r"]), float(r["g"]), float(r["b"])] for r in rows])
    except (OSError, UnicodeDecodeError) as error:
        raise DngError(path, f"cannot read sensitivity CSV ({error})") from None
    except (TypeError, ValueError):
        raise DngError(path, "a row is not four numbers") from None
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
    if head.startswith("{"):
        return read_rawtoaces_json(path)
    if head.lower().startswith("wavelength"):
        return read_csv(path)
    cameras = read_camspec(path)
    if camera is not None:
        return read_camspec(path, camera)
    if len(cameras) == 1:
        return next(iter(cameras.values()))
    raise DngError(path, f"a camspec file with {len(cameras)} cameras: name one (e.g. {next(iter(cameras))!r})")
