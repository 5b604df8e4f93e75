"""Highlights (issue 8): by default a grey surface below clipping is recorded at the camera
neutral's channel ratios, as a sensor records it, and renders grey in LibRaw; the highlight-safe
gains of Brooks et al. (kept for the published recipe and on request) tint it magenta.
The full measurement is benchmarks/highlights.py (figures in the README, "Highlights")."""

from __future__ import annotations

import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("rawpy")
pytest.importorskip("colour_hdri")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import highlights as hl  # noqa: E402

from g2r_jax.profile.schema import load_profile  # noqa: E402
from g2r_jax.pipeline import unprocess, without_content  # noqa: E402


@pytest.fixture(scope="module")
def profile():
    return without_content(load_profile("Canon600D"))   # grey in, grey out: no CG content model


@pytest.mark.parametrize("cct", [2900.0, pytest.param(6500.0, marks=pytest.mark.slow)])
def test_default_records_grey_at_the_neutral_and_renders_grey(tmp_path, profile, cct):
    neutral = hl.neutral_for(profile, cct)
    default = hl.measure(profile, neutral, 0.5, None, tmp_path)       # None: the default for recipe 'dng'
    safe = hl.measure(profile, neutral, 0.5, True, tmp_path)
    assert default["clipped_patches"] == 0
    assert default["raw_ratio_error"] < 0.01                          # quantisation only
    assert default["libraw_max_chroma"] < 1.0 and default["colour_hdri_max_chroma"] < 1.0
    assert max(default["libraw_white_srgb8"]) - min(default["libraw_white_srgb8"]) <= 2
    # the eased gains record R = G = B below clipping: renderers white-balance that into magenta
    assert safe["raw_ratio_error"] > 0.5 and safe["libraw_max_chroma"] > 20


def test_published_recipe_keeps_the_safe_gains(profile):
    white = jnp.ones((2, 2, 3), jnp.float32)
    args = dict(noise=False, neutral=jnp.array([0.5, 1.0, 0.7]), quantize=False, recipe="published")
    default, _ = unprocess(jax.random.PRNGKey(0), white, profile, **args)
    safe, _ = unprocess(jax.random.PRNGKey(0), white, profile, highlight_safe=True, **args)
    np.testing.assert_array_equal(np.asarray(default), np.asarray(safe))
