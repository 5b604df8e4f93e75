"""The CIE/sRGB constants copied from colour-science at build time (`g2r_jax.colour.cie_constants`)
still equal the library's, bit for bit; and converting images does not import colour-science."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from g2r_jax.colour import build_constants, cie_constants, conversions


def test_copied_constants_equal_colour_science():
    library = build_constants.library_constants()
    for name, value in library.items():
        copied = np.asarray(getattr(cie_constants, name), np.float64)
        assert copied.shape == value.shape and np.array_equal(copied, value), name
    assert np.array_equal(conversions.MATRIX_SRGB_TO_XYZ, library["MATRIX_SRGB_TO_XYZ"])
    assert np.array_equal(conversions.XY_D50, library["XY_D50"])


def test_the_generated_module_is_what_the_build_step_writes():
    text = build_constants.module_text(build_constants.library_constants())
    assert build_constants.TARGET.read_text() == text, "rerun python -m g2r_jax.colour.build_constants"


def test_converting_does_not_import_colour_science_or_the_audit():
    code = ("import sys, g2r_jax.batch.conversion, g2r_jax.cli.convert, g2r_jax.profile.schema\n"
            "heavy = [m for m in sys.modules if m.split('.')[0] in ('colour', 'matplotlib') "
            "or m.startswith('g2r_jax.audit')]\n"
            "print(heavy)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"
