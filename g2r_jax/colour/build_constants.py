"""Write `g2r_jax/colour/cie_constants.py` from colour-science (offline, when colour-science changes).

    python -m g2r_jax.colour.build_constants

The constants the conversions need (CIE 1931 2-degree whitepoints of D50, D65 and Standard
Illuminant A; the sRGB RGB -> XYZ matrix of IEC 61966-2-1; the Bradford cone matrix; Robertson's
1968 isotemperature lines) are copied out of colour-science as exact float64 literals, so that
converting an image does not import colour-science (whose import pulls in its plotting package and
matplotlib). tests/test_colour_constants.py checks that the copies still equal the library's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

TARGET = Path(__file__).with_name("cie_constants.py")
_OBSERVER = "CIE 1931 2 Degree Standard Observer"


def library_constants() -> dict[str, np.ndarray]:
    """The constants as colour-science holds them, float64, keyed by their name in the module."""
    import colour
    from colour.temperature.robertson1968 import DATA_ISOTEMPERATURE_LINES_ROBERTSON1968

    whites = colour.CCS_ILLUMINANTS[_OBSERVER]
    return {
        "XY_D50": np.asarray(whites["D50"], np.float64),
        "XY_D65": np.asarray(whites["D65"], np.float64),
        "XY_A": np.asarray(whites["A"], np.float64),
        "MATRIX_SRGB_TO_XYZ": np.asarray(colour.models.RGB_COLOURSPACE_sRGB.matrix_RGB_to_XYZ, np.float64),
        "MATRIX_BRADFORD": np.asarray(colour.adaptation.CAT_BRADFORD, np.float64),
        "ROBERTSON_1968": np.asarray(DATA_ISOTEMPERATURE_LINES_ROBERTSON1968, np.float64),
    }


def _literal(array: np.ndarray) -> str:
    """Nested tuples of exact float reprs (repr of a float64 round-trips)."""
    if array.ndim == 1:
        return "(" + ", ".join(repr(float(v)) for v in array) + ("," if len(array) == 1 else "") + ")"
    return "(\n    " + ",\n    ".join(_literal(row) for row in array) + ",\n)"


def module_text(constants: dict[str, np.ndarray]) -> str:
    """Source of the generated module."""
    lines = ['"""CIE and sRGB constants copied from colour-science by `build_constants.py` (do not edit;',
             "rerun `python -m g2r_jax.colour.build_constants`). Plain tuples: numpy arrays are made from",
             'them in `conversions`."""', ""]
    for name, value in constants.items():
        lines += [f"{name} = {_literal(value)}", ""]
    return "\n".join(lines)


def main() -> None:
    TARGET.write_text(module_text(library_constants()))
    print(f"wrote {TARGET}")


if __name__ == "__main__":
    main()
