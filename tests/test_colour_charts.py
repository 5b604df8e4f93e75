"""Measured colour charts: CSV format, prediction through the DNG colour model, ColorMatrix refit,
and the `colour_matrix` audit (hidden matrix error found with a held-out gain; clean charts: nothing)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from g2r_jax.colour import charts as C
from g2r_jax.measure import angular_error_degrees
from g2r_jax.colour import chart_fit as F
from g2r_jax.pipeline import simulate_patches
from g2r_jax.audit import diagnose, synthetic
from g2r_jax.colour.dng_model import DngColourModel
from g2r_jax.profile.schema import load_profile, replace, save_profile

PROFILE = "profiles/Canon600D.json"


def single_matrix_profile():
    """The Canon 600D profile reduced to its D65 matrix (a camera whose DNG carries one matrix)."""
    return synthetic.single_matrix_profile(load_profile(PROFILE))


perturbed = synthetic.perturbed_colour         # CM -> (I + size * N(0, 1)) CM, as the only (D65) matrix
synthetic_charts = synthetic.simulated_charts  # charts that camera records (1 % noise, 3 % NaN, 3 folds)


# ------------------------------------------------------------------------------------ format

def test_chart_csv_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    patches = rng.uniform(1, 100, (3, 24, 3))
    patches[1, 5] = np.nan
    charts = C.ChartSet(["a", "b", "c"], patches, rng.uniform(1, 2, (3, 3)), np.array([0, 1, 2]))
    C.write_charts(tmp_path / "c.csv", charts)
    back = C.read_charts(tmp_path / "c.csv")
    assert back.images == ["a", "b", "c"]
    np.testing.assert_array_equal(np.isnan(back.patches), np.isnan(patches))
    np.testing.assert_allclose(back.patches[np.isfinite(patches)], patches[np.isfinite(patches)])
    np.testing.assert_allclose(back.illuminant, charts.illuminant)
    np.testing.assert_array_equal(back.folds, [0, 1, 2])


@pytest.mark.parametrize("body, message", [
    ("image,patch,r,g\n", "row 1: header"),
    ("image,patch,r,g,b\na,1,1,2,3\n", "'a' has no 'illuminant' row"),
    ("image,patch,r,g,b\na,25,1,2,3\na,illuminant,1,1,1\n", "row 2: patch '25'"),
    ("image,patch,r,g,b\na,1,1,x,3\na,illuminant,1,1,1\n", "row 2: 'x' is not a number"),
    ("image,patch,r,g,b\na,illuminant,1,nan,1\n", "row 2: the illuminant"),
    ("image,patch,r,g,b\na,1,1,2,3\na,1,1,2,3\n", "row 3: second row"),
    ("image,patch,r,g,b\na,1,1,2\n", "row 2: expected 5 fields"),
    ("", "empty file"),
])
def test_chart_csv_errors_name_file_and_row(tmp_path, body, message):
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(C.ChartError) as error:
        C.read_charts(path)
    text = str(error.value)
    assert str(path) in text and message in text and "\n" not in text


def test_chart_colours_from_colour_science():
    linear = C.chart_linear_srgb()
    assert linear.shape == (24, 3)
    white = linear[18]
    assert 0.85 < white.mean() < 0.92 and np.ptp(white) < 0.02     # ~90 % reflectance, neutral under D65
    assert linear[17, 0] < 0 and np.all(C.chart_srgb() >= 0)       # cyan outside sRGB; encoded chart clipped


# ----------------------------------------------------------------------------------- prediction

def test_closed_form_prediction_is_unprocess():
    """`predict_patches` (used for fitting) equals patch means of `unprocess_batch` mosaics."""
    profile = load_profile(PROFILE)
    neutrals = np.array([[0.45, 1, 0.75], [0.6, 1, 0.5], [0.35, 1, 0.9]])
    chart = C.chart_srgb()
    chart[18] = 0.7                      # an exactly neutral patch
    simulated = simulate_patches(profile, neutrals, chart)
    from g2r_jax.colour.conversions import srgb_to_linear

    charts = C.ChartSet(["a", "b", "c"], simulated, neutrals)
    predicted = F.predict_patches_np(profile.colour, charts, np.asarray(srgb_to_linear(chart), np.float64))
    assert np.nanmax(angular_error_degrees(predicted, simulated, invalid="nan")) < 0.02
    # white stays exact: a neutral patch is recorded as the image's neutral
    assert np.max(angular_error_degrees(simulated[:, 18], neutrals)) < 0.02


def test_implicit_derivative_of_the_white_point():
    """d(prediction)/d(matrix) through the DNG white-point solve matches finite differences."""
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from g2r_jax.runtime.x64 import enable_x64

    profile = load_profile(PROFILE)
    with enable_x64():
        pair = jnp.asarray(np.asarray(profile.colour.color_matrix, np.float64))
        base = DngColourModel.from_tags((17, 21), list(np.asarray(pair)), dtype=np.float64)
        neutral = jnp.asarray([[0.5, 1.0, 0.7]])
        chart = jnp.asarray(C.chart_linear_srgb()[:3])

        def f(p):
            model = eqx.tree_at(lambda m: m.color_matrix, base, p)
            out = F.predict_patches(model, neutral, chart)
            return (out / jnp.linalg.norm(out, axis=-1, keepdims=True)).reshape(-1)

        direction = jnp.asarray(np.random.default_rng(1).normal(size=pair.shape))
        _, tangent = jax.jvp(f, (pair,), (direction,))
        step = 1e-6
        numeric = (f(pair + step * direction) - f(pair - step * direction)) / (2 * step)
        np.testing.assert_allclose(np.asarray(tangent), np.asarray(numeric), atol=1e-6, rtol=1e-4)


# --------------------------------------------------------------------------------------- refit

def test_refit_recovers_a_hidden_matrix_and_round_trips(tmp_path):
    """Refit on charts of a camera with a perturbed matrix: errors drop to the noise level, and
    a DNG written with the refitted profile renders (colour_hdri) back to the input."""
    pytest.importorskip("colour_hdri")
    from test_roundtrip import round_trip_delta_E

    profile = single_matrix_profile()
    truth = perturbed(profile, np.random.default_rng(3))
    charts = synthetic_charts(truth, 30, seed=1)
    before = F.summarise(F.colour_model_errors(profile.colour, charts))["chromatic_mean"]
    model, codes = F.refit_colour_matrices(F.as_pair(profile.colour, (21,)), charts, max_steps=40)
    after = F.summarise(F.colour_model_errors(model, charts))["chromatic_mean"]
    assert after < 0.5 * before and after < 1.0, (before, after)
    refitted = F.with_colour(profile, model, codes)
    save_profile(refitted, tmp_path / "refit.json")
    assert load_profile(tmp_path / "refit.json").info.calibration_illuminants == (17, 21)
    assert round_trip_delta_E(tmp_path, tmp_path / "refit.json", 4000) <= 0.3


# --------------------------------------------------------------------------------------- audit

def test_audit_finds_a_hidden_colour_matrix_error(tmp_path):
    rng = np.random.default_rng(11)
    profile = single_matrix_profile()
    truth = perturbed(profile, rng)
    charts = synthetic_charts(truth, 30, seed=2)
    report = diagnose(profile, charts=charts, n_permutations=500)
    top = report["findings"][0]
    assert top["cause"] == "colour_matrix" and top["significant"] and top["kept"], top["evidence"]
    assert top["gain"]["heldout"] and top["gain"]["after"] < 0.5 * top["gain"]["before"], top["gain"]
    extended = report["profile"]
    assert extended.info.calibration_illuminants == (17, 21)
    assert F.summarise(F.colour_model_errors(extended.colour, charts))["chromatic_mean"] < 1.0
    assert "colour_matrix" in report["vocabulary"]
    plot = top["plot"]                 # the report's case: per patch, before and held-out after
    assert plot["kind"] == "patches" and len(plot["labels"]) == len(plot["before"]) == len(plot["after"]) == 24
    assert np.nanmean(np.asarray(plot["after"])[C.CHROMATIC]) < 0.5 * np.nanmean(np.asarray(plot["before"])[C.CHROMATIC])
    from g2r_jax.audit.report import write_html

    page = write_html(report, tmp_path / "html")
    assert (tmp_path / "html" / "finding_0_colour_matrix.png").stat().st_size > 1000
    assert "finding_0_colour_matrix.png" in page.read_text()


def test_audit_finds_nothing_on_clean_charts():
    profile = single_matrix_profile()
    charts = synthetic_charts(profile, 30, seed=4)
    report = diagnose(profile, charts=charts, n_permutations=500)
    assert not any(f["significant"] for f in report["findings"]), [f["evidence"] for f in report["findings"]]
    assert report["profile"] is profile


def test_cli_charts_only(tmp_path, capsys):
    from g2r_jax.cli.diagnose import main

    profile = single_matrix_profile()
    save_profile(profile, tmp_path / "p.json")
    C.write_charts(tmp_path / "charts.csv", synthetic_charts(perturbed(profile, np.random.default_rng(5)), 30, seed=6))
    status = main(["--profile", str(tmp_path / "p.json"), "--charts", str(tmp_path / "charts.csv"),
                   "--report", str(tmp_path / "r.json"), "--extended-profile", str(tmp_path / "ext.json"), "--quiet"])
    assert status == 0
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["findings"][0]["cause"] == "colour_matrix"
    assert load_profile(tmp_path / "ext.json").info.calibration_illuminants == (17, 21)
    (tmp_path / "bad.csv").write_text("image,patch,r,g,b\na,1,1,2\n")
    status = main(["--profile", str(tmp_path / "p.json"), "--charts", str(tmp_path / "bad.csv"),
                   "--report", str(tmp_path / "r2.json"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "bad.csv: row 2" in err[0]


# ------------------------------------------------------------------------------- real charts

@pytest.mark.data
@pytest.mark.slow
def test_real_canon_5d_charts(shared_data, tmp_path):
    """Gehler-Shi Canon EOS 5D (482 images) with its Adobe D65 matrix: colour_matrix first, the
    refit brings the held-out chromatic mean angular error from ~4.5 deg to 2.7 deg or less."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location("gehler_shi_charts", Path("benchmarks/gehler_shi_charts.py"))
    converter = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(converter)
    assert converter.main(["--data", str(shared_data), "-o", str(tmp_path)]) == 0
    charts = C.read_charts(tmp_path / "gehler_shi_5d.csv")
    assert len(charts) == 482 and np.bincount(charts.folds).tolist() == [158, 159, 165]
    profile = load_profile(tmp_path / "gehler_shi_5d.json")
    report = diagnose(profile, charts=charts, n_permutations=500)
    top = report["findings"][0]
    assert top["cause"] == "colour_matrix" and top["significant"] and top["kept"]
    assert 4.0 < top["gain"]["before"] < 5.0 and top["gain"]["after"] <= 2.7, top["gain"]


def test_audit_with_dngs_and_charts():
    """Both kinds of evidence in one run: colour first from the charts, the sensor causes from
    the files, tested against the colour-extended profile; the extended profile keeps both."""
    from audit_helpers import dark_frames, measured_set

    from g2r_jax.audit import causes, synthetic

    base = synthetic.demo_profile()
    error = np.eye(3) + 0.12 * np.random.default_rng(8).normal(size=(3, 3))
    truth = replace(base, colour=DngColourModel.from_tags(
        (17, 21), [error @ np.asarray(m, np.float64) for m in base.colour.color_matrix]))
    camera = synthetic.inject(base, "black_level", offset=0.02)
    files = (measured_set(camera, 3, n=10, height=60, width=90)     # the pedestal's evidence: dark frames
             + dark_frames(camera, 3, height=60, width=90))
    registry = (causes.get("black_level"), causes.get("colour_matrix"))
    report = diagnose(base, files, charts=synthetic_charts(truth, 30, seed=9), seed=0, n_simulated=10,
                      causes=registry, n_permutations=300)
    found = {f["cause"]: f for f in report["findings"] if f["significant"]}
    assert {"black_level", "colour_matrix"} <= set(found), [(f["cause"], f["evidence"]) for f in report["findings"]]
    assert found["colour_matrix"]["kept"] and report["tests"] == 2 and report["n_charts"] == 30
    extended = report["profile"]
    assert float(np.max(extended.effects.black_pedestal)) > 0
    assert not np.allclose(np.asarray(extended.colour.color_matrix), np.asarray(base.colour.color_matrix))
