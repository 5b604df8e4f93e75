"""How much of an illuminant model the files' lights weigh (illuminants/choice.py `LightShares`),
the line g2r-fit-profile prints and the provenance it stores, and the pool's exclusion through
'auto' (the leave-one-dataset-out benchmark's `auto-gs`, benchmarks/few_lights.py)."""

import re

import numpy as np
import pytest

from g2r_jax.content.prior import NUS_CAMERAS
from g2r_jax.illuminants import choice as ch
from g2r_jax.illuminants import kernel as kd
from g2r_jax.illuminants import pooled as po
from g2r_jax.profile.schema import load_profile

SHARES = re.compile(r"lights: (\d+) distinct measured lights? weighs? (\d+) %(?:, (.+?) (\d+) %)?(?:;|$)")
# lights on the Canon 600D's daylight-to-tungsten band (r/g, b/g), distinct
LIGHTS = np.array([[0.46, 0.66], [0.48, 0.64], [0.52, 0.60], [0.62, 0.52], [0.45, 0.67], [0.75, 0.42],
                   [0.47, 0.65], [0.50, 0.62], [0.55, 0.57], [0.58, 0.55], [0.68, 0.47], [0.44, 0.68],
                   [0.49, 0.63], [0.51, 0.61], [0.53, 0.59], [0.57, 0.56]])


@pytest.fixture(scope="module")
def colour():
    return load_profile("Canon600D").colour


def stated(reason: str):
    """(lights, files %, other words, other %) of the one shares clause of a reason."""
    found = SHARES.findall(reason)
    assert len(found) == 1, reason
    lights, files, other, rest = found[0]
    return int(lights), int(files), other, int(rest) if rest else None


def test_the_words_sum_to_100_and_name_both_parts():
    for n, files in ((0, 0.0), (1, 1 / 6), (3, 0.375), (7, 0.125), (9, 0.875), (12, 12 / 17), (400, 400 / 405)):
        words = ch.shares_words(ch.LightShares(n, files, "the pooled lights of 3 other cameras"))
        lights, shown, other, rest = stated(words)
        assert lights == n and other == "the pooled lights of 3 other cameras"
        assert shown + rest == 100 and abs(shown - 100 * files) <= 0.5, words
    assert "1 distinct measured light weighs" in ch.shares_words(ch.LightShares(1, 0.5, "x"))
    alone = ch.shares_words(ch.LightShares(5, 1.0, ""))
    assert alone == "lights: 5 distinct measured lights weigh 100 %"


def test_auto_states_the_blend_its_model_holds_and_the_files_gain_with_more_lights(colour):
    """Every model 'auto' picks from the lights (pooled below 10, the kernel from 10): the share
    stated is the weight of the files' kernels in the fitted mixture (they come first), the
    Dirichlet-process n / (n + n0), and it grows with the number of lights."""
    pool = po.load_pooled()
    own = set(po.same_camera_sources(colour, po.load_pool_matrices()))
    before = -1.0
    for n in (0, 1, 3, ch.MIN_LIGHTS_FOR_KERNEL - 1, ch.MIN_LIGHTS_FOR_KERNEL, len(LIGHTS)):
        chosen = ch.choose_illuminant_model(LIGHTS[:n], colour)
        shares = chosen.shares
        assert shares.lights == chosen.lights == n
        np.testing.assert_allclose(shares.files + shares.rest, 1.0)
        np.testing.assert_allclose(shares.files, n / (n + kd.PRIOR_PSEUDO_LIGHTS), rtol=1e-12)
        np.testing.assert_allclose(np.sum(np.asarray(chosen.model.weights, np.float64)[:n]), shares.files, atol=1e-6)
        assert shares.files > before
        before = shares.files
        lights, files, other, rest = stated(chosen.reason)
        assert (lights, files, rest) == (n, round(100 * shares.files), 100 - round(100 * shares.files))
        if n < ch.MIN_LIGHTS_FOR_KERNEL:
            assert chosen.reason.startswith("pooled (auto")
            assert set(shares.sources) == set(pool) - own and own   # the camera's own NUS lights left out
            assert other == f"the pooled lights of {len(pool) - len(own)} other cameras"
        else:
            assert chosen.reason.startswith("kernel (auto") and other == ch.PRIOR_WORDS and shares.sources == ()


def test_models_without_the_lights_weigh_them_zero_and_those_of_the_lights_alone_all(colour):
    for kind, other in (("prior", ch.PRIOR_WORDS), ("locus", ch.LOCUS_WORDS)):
        for n in (0, 4):
            chosen = ch.choose_illuminant_model(LIGHTS[:n], colour, kind)
            assert chosen.shares.files == 0.0 and stated(chosen.reason) == (n, 0, other, 100)
    for kind in ("gaussian", "mixture"):
        chosen = ch.choose_illuminant_model(LIGHTS, colour, kind)
        assert chosen.shares.files == 1.0 and stated(chosen.reason) == (len(LIGHTS), 100, "", None)
    kernel = ch.choose_illuminant_model(LIGHTS[:2], colour, "kernel")
    np.testing.assert_allclose(np.sum(np.asarray(kernel.model.weights, np.float64)[:2]), kernel.shares.files, atol=1e-6)
    assert stated(kernel.reason)[1:3] == (round(100 * 2 / (2 + kd.PRIOR_PSEUDO_LIGHTS)), ch.PRIOR_WORDS)


def test_auto_without_the_nus_cameras_uses_the_gehler_shi_lights_alone(colour):
    """The leave-one-dataset-out default (`auto-gs`): at 0 and 1 lights 'auto' with every NUS
    camera excluded is the pooled model of a pool holding only the other sources (the Gehler-Shi
    Canons), and not the full pool's; from 10 lights it is the kernel, which no pool enters."""
    pool = po.load_pooled()
    others = {name: points for name, points in pool.items() if name not in NUS_CAMERAS}
    assert set(others) == {"Canon EOS-1D", "Canon EOS 5D"}
    tangents = lambda p: ch.camera_locus_tangents(p, colour)   # noqa: E731
    alone = po.pooled_base(colour, tangents, pool=others)
    for n in (0, 1):
        chosen = ch.choose_illuminant_model(LIGHTS[:n], colour, "auto", exclude=NUS_CAMERAS)
        assert chosen.reason.startswith("pooled (auto") and set(chosen.shares.sources) == set(others)
        assert "the pooled lights of 2 other cameras" in chosen.reason
        expected, _ = po.fit_pooled(LIGHTS[:n], colour, tangents, base=alone)
        for field in ("weights", "means", "cholesky"):
            np.testing.assert_allclose(np.asarray(getattr(chosen.model, field)), np.asarray(getattr(expected, field)),
                                       rtol=1e-5, atol=1e-7)
        full = ch.choose_illuminant_model(LIGHTS[:n], colour, "auto")
        assert len(full.model.weights) > len(chosen.model.weights)
    many = LIGHTS[:ch.MIN_LIGHTS_FOR_KERNEL]
    for field in ("weights", "means"):
        np.testing.assert_array_equal(
            np.asarray(getattr(ch.choose_illuminant_model(many, colour, "auto", exclude=NUS_CAMERAS).model, field)),
            np.asarray(getattr(ch.choose_illuminant_model(many, colour, "auto").model, field)))


@pytest.mark.parametrize("count", [1, 12])
def test_fit_profile_prints_and_stores_the_shares(tmp_path, capsys, count):
    """The illuminant line of g2r-fit-profile names both parts with their weights (cut to one
    line's length, it still holds them), and the profile's provenance holds the same clause."""
    import json

    from g2r_jax.cli import fit_profile
    from g2r_jax.profile.shipped import SHIPPED_PROFILES_DIR

    csv = tmp_path / "lights.csv"
    csv.write_text("r_over_g,g,b_over_g\n" + "".join(f"{r},1,{b}\n" for r, b in LIGHTS[:count]))
    out = tmp_path / "camera.json"
    assert fit_profile.main(["--illuminants", str(csv), "--calibration", str(SHIPPED_PROFILES_DIR / "Canon600D.json"),
                             "-o", str(out)]) == 0
    line = [x for x in capsys.readouterr().out.splitlines() if x.startswith("g2r-fit-profile: illuminant model:")]
    assert len(line) == 1
    files = round(100 * count / (count + kd.PRIOR_PSEUDO_LIGHTS))
    lights, shown, other, rest = stated(line[0].split(": ", 2)[2])
    assert (lights, shown, rest) == (count, files, 100 - files)
    colour = load_profile(SHIPPED_PROFILES_DIR / "Canon600D.json").colour
    sources = set(po.load_pooled()) - set(po.same_camera_sources(colour, po.load_pool_matrices()))
    assert other == (ch.PRIOR_WORDS if count >= ch.MIN_LIGHTS_FOR_KERNEL
                     else f"the pooled lights of {len(sources)} other cameras")
    provenance = json.loads(out.read_text())["provenance"]
    assert stated(provenance.rpartition("; illuminants: ")[2]) == (lights, shown, other, rest)
