"""Measured colour charts: the CSV format, its reader and writer, and the chart's known colours.

**Chart CSV format** (one row per image and patch; UTF-8, comma-separated, header required):

    image,patch,r,g,b[,fold]
    8D5U5524,1,114.0,113.0,53.0
    8D5U5524,2,335.0,356.0,189.0
    ...
    8D5U5524,illuminant,769.0,1043.0,653.0

- `image`: any identifier without commas (a file stem); rows of one image need not be adjacent.
- `patch`: 1..24, the X-Rite ColorChecker Classic in its standard order (1 dark skin ... 19 white,
  24 black; the order of `colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]`), or `illuminant`
  for the image's measured neutral (camera RGB of a neutral surface under the scene's light).
- `r, g, b`: linear raw camera RGB with the black level removed (any linear unit: DN, or DN
  normalised to the range), averaged per channel over the patch. `nan` (or an empty field) marks
  an unusable patch (saturated, too dark, occluded); the patch is then ignored, not the image.
- `fold` (optional): the image's cross-validation fold (integer >= 0), as in a dataset's standard
  split (Gehler-Shi: 3 folds). Without it, folds are drawn by `assign_folds`.

Every image must have an `illuminant` row with finite, positive values whose r/g and b/g lie in
[1e-6, 1e6]. Missing patch rows are NaN; at least one image needs a measured chromatic patch
(1..18). A bad file raises `ChartError` with one line naming the file and row.

The chart's colours: the 24 spectral reflectances of colour-science's "ColorChecker N Ohta"
(Ohta's measurements as distributed with colour-science) integrated under CIE D65 with the CIE
1931 2-degree observer (`colour.sd_to_XYZ`, ASTM E308 integration) and converted to linear sRGB
(IEC 61966-2-1 primaries, D65 white; no adaptation is needed). The cyan patch (18) lies slightly
outside the sRGB gamut; its linear value is kept unclipped. The built-in example scene's
patches (`colour_checker_2014_srgb`) are another data set: colour-science's "ColorChecker24 -
After November 2014" CIE xyY (D50), Bradford-adapted to sRGB's D65.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import io
import math
from pathlib import Path
import warnings

import numpy as np

N_PATCHES = 24
CHROMATIC = np.arange(18)          # patches 1-18 (0-based 0..17)
NEUTRAL = np.arange(18, 24)        # patches 19-24: white ... black
MIN_RATIO = 1e-6                    # an illuminant's r/g and b/g beyond [1e-6, 1e6] is not a light
ILLUMINANT = "illuminant"
PATCH_NAMES = (
    "dark skin", "light skin", "blue sky", "foliage", "blue flower", "bluish green",
    "orange", "purplish blue", "moderate red", "purple", "yellow green", "orange yellow",
    "blue", "green", "red", "yellow", "magenta", "cyan",
    "white 9.5", "neutral 8", "neutral 6.5", "neutral 5", "neutral 3.5", "black 2",
)
COLUMNS = ("image", "patch", "r", "g", "b")


class ChartError(ValueError):
    """A chart file that cannot be used; the message names the file and the row."""


@dataclasses.dataclass
class ChartSet:
    """Measured charts of one camera: `patches` (N, 24, 3) linear raw RGB (NaN = unusable),
    `illuminant` (N, 3) each image's measured neutral, `images` (N,) identifiers, `folds` (N,)
    int or None, and `source` (the file they came from)."""

    images: list
    patches: np.ndarray
    illuminant: np.ndarray
    folds: np.ndarray | None = None
    source: str = "<charts>"

    def __len__(self) -> int:
        return len(self.images)

    def subset(self, index) -> "ChartSet":
        index = np.asarray(index)
        return ChartSet([self.images[i] for i in np.arange(len(self))[index]], self.patches[index],
                        self.illuminant[index], None if self.folds is None else self.folds[index], self.source)


def _number(text: str, where: str) -> float:
    text = text.strip()
    if text == "" or text.lower() == "nan":
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise ChartError(f"{where}: {text!r} is not a number") from None
    if math.isinf(value):
        raise ChartError(f"{where}: infinite value")
    return value


def read_charts(path) -> ChartSet:
    """Read a chart CSV (format in the module docstring). Raises ChartError naming file and row."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ChartError(f"{path}: no such chart file") from None
    except (UnicodeDecodeError, IsADirectoryError, PermissionError) as error:
        raise ChartError(f"{path}: cannot be read as a UTF-8 text file ({type(error).__name__})") from None
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if header is None:
        raise ChartError(f"{path}: empty file (expected the header {','.join(COLUMNS)})")
    header = [h.strip().lower() for h in header]
    if tuple(header[:5]) != COLUMNS or header[5:] not in ([], ["fold"]):
        raise ChartError(f"{path}: row 1: header must be {','.join(COLUMNS)} (optionally ,fold), got {','.join(header)}")
    has_fold = len(header) == 6
    images, patches, illuminants, folds = {}, {}, {}, {}
    for row_number, row in enumerate(reader, start=2):
        where = f"{path}: row {row_number}"
        if not row or all(not field.strip() for field in row):
            continue
        if len(row) != len(header):
            raise ChartError(f"{where}: expected {len(header)} fields, got {len(row)}")
        image, patch = row[0].strip(), row[1].strip().lower()
        if not image:
            raise ChartError(f"{where}: empty image identifier")
        rgb = [_number(v, where) for v in row[2:5]]
        index = images.setdefault(image, len(images))
        if has_fold:
            fold = _number(row[5], where)
            if not (fold >= 0 and float(fold).is_integer()):
                raise ChartError(f"{where}: fold {row[5]!r} is not an integer >= 0")
            if folds.setdefault(index, int(fold)) != int(fold):
                raise ChartError(f"{where}: image {image!r} has fold {int(fold)} here and {folds[index]} on an earlier row")
        if patch == ILLUMINANT:
            if index in illuminants:
                raise ChartError(f"{where}: second illuminant row for image {image!r}")
            if not all(math.isfinite(v) and v > 0 for v in rgb):
                raise ChartError(f"{where}: the illuminant of image {image!r} must be finite and positive, got {rgb}")
            if not all(MIN_RATIO <= v / rgb[1] <= 1 / MIN_RATIO for v in rgb):
                raise ChartError(f"{where}: the illuminant of image {image!r} is degenerate (r/g and b/g must lie "
                                 f"in [{MIN_RATIO:g}, {1 / MIN_RATIO:g}]), got {rgb}")
            illuminants[index] = rgb
            continue
        try:
            number = int(patch)
        except ValueError:
            number = 0
        if not 1 <= number <= N_PATCHES or str(number) != patch:
            raise ChartError(f"{where}: patch {row[1]!r} is neither 1..{N_PATCHES} nor '{ILLUMINANT}'")
        if (index, number) in patches:
            raise ChartError(f"{where}: second row for image {image!r} patch {number}")
        patches[(index, number)] = rgb
    if not images:
        raise ChartError(f"{path}: no chart rows")
    names = list(images)
    missing = [name for name, i in images.items() if i not in illuminants]
    if missing:
        raise ChartError(f"{path}: image {missing[0]!r} has no '{ILLUMINANT}' row"
                         + (f" (and {len(missing) - 1} more images)" if len(missing) > 1 else ""))
    values = np.full((len(names), N_PATCHES, 3), np.nan)
    for (index, number), rgb in patches.items():
        values[index, number - 1] = rgb
    if not np.isfinite(values[:, CHROMATIC]).all(-1).any():
        raise ChartError(f"{path}: no image has a measured chromatic patch (1..18, all nan or missing): "
                         "nothing to compare")
    return ChartSet(names, values, np.array([illuminants[i] for i in range(len(names))], float),
                    np.array([folds[i] for i in range(len(names))]) if has_fold else None, str(path))


def charts_to_csv_text(charts: ChartSet) -> str:
    """The chart CSV text of a ChartSet (NaN written as `nan`)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    has_fold = charts.folds is not None
    writer.writerow(COLUMNS + (("fold",) if has_fold else ()))
    fmt = lambda v: "nan" if not np.isfinite(v) else repr(float(v))
    for i, image in enumerate(charts.images):
        extra = [int(charts.folds[i])] if has_fold else []
        for p in range(N_PATCHES):
            writer.writerow([image, p + 1, *map(fmt, charts.patches[i, p]), *extra])
        writer.writerow([image, ILLUMINANT, *map(fmt, charts.illuminant[i]), *extra])
    return out.getvalue()


def write_charts(path, charts: ChartSet) -> None:
    """Write a chart CSV atomically (temporary file, then rename)."""
    from g2r_jax.io.atomic import atomic_write_bytes

    atomic_write_bytes(Path(path), charts_to_csv_text(charts).encode("utf-8"))


def assign_folds(n: int, folds: int = 3, seed: int = 0) -> np.ndarray:
    """Fold of each of n images: a seeded permutation dealt round-robin (sizes differ by <= 1),
    the folds of `g2r_jax.measure.folds_of` as one label per image."""
    from g2r_jax.measure import folds_of

    out = np.empty(n, int)
    for fold, held in enumerate(folds_of(n, folds, seed)):
        out[held] = fold
    return out


def folds_of(charts: ChartSet, folds: int = 3, seed: int = 0) -> np.ndarray:
    """The file's folds if it has them, else `assign_folds`."""
    return charts.folds if charts.folds is not None else assign_folds(len(charts), folds, seed)


@functools.lru_cache(maxsize=1)
def _chart_linear_srgb() -> np.ndarray:
    import colour

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    sds = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    with warnings.catch_warnings():   # colour-science notes that it aligns the spectra's range
        warnings.simplefilter("ignore")
        XYZ = np.array([colour.sd_to_XYZ(sd, cmfs, d65) for sd in sds.values()]) / 100.0
    return colour.XYZ_to_RGB(XYZ, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)


def chart_linear_srgb() -> np.ndarray:
    """(24, 3) linear sRGB of the ColorChecker N Ohta reflectances under CIE D65 (white of a
    perfect diffuser = Y 1), unclipped; see the module docstring for the source."""
    return _chart_linear_srgb().copy()


def colour_checker_2014_srgb() -> np.ndarray:
    """(24, 3) sRGB-encoded values in [0, 1] of the "ColorChecker24 - After November 2014" patches
    (colour-science's xyY under D50, Bradford chromatic adaptation to sRGB; clipped): the
    patches of the built-in example scene (`g2r_jax.examples`)."""
    import colour

    checker = colour.CCS_COLOURCHECKERS["ColorChecker24 - After November 2014"]
    XYZ = colour.xyY_to_XYZ(np.array(list(checker.data.values())))
    rgb = colour.XYZ_to_sRGB(XYZ, illuminant=checker.illuminant, chromatic_adaptation_transform="Bradford")
    return np.clip(rgb, 0, 1)


def chart_srgb() -> np.ndarray:
    """(24, 3) sRGB-encoded chart colours in [0, 1] (linear values clipped to [0, 1] first)."""
    from g2r_jax.colour.conversions import linear_to_srgb

    return np.asarray(linear_to_srgb(np.clip(chart_linear_srgb(), 0.0, 1.0)), np.float64)
