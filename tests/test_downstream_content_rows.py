"""The content model's rows of the downstream experiment (issue 32): the model is fitted to the
training folds only (and the benchmark's selection sees only them), a profile's own model is used as given, `g2r-downstream --content-rows` reports
both rows, and an unknown row is refused by name."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest
from downstream_helpers import write_camera_folders

import g2r_jax
from g2r_jax.downstream.base import product, real_sets, training_sets
from g2r_jax.downstream.illuminant import content_rows, estimators, experiment
from g2r_jax.measure import folds_of
from g2r_jax.pipeline import without_content


def _real_set(count=12, seed=0):
    """Distinct random thumbnails under lights drawn from NikonD40's own illuminant model."""
    from g2r_jax.illuminants.distributions import sample_neutrals

    profile = without_content(g2r_jax.load_profile("NikonD40"))   # the rows fit their own per fold
    lights = np.asarray(sample_neutrals(jax.random.PRNGKey(seed), profile.illuminants, count), np.float64)
    images = np.random.default_rng(seed).random((count, 64, 64, 3)).astype(np.float32)
    return real_sets.RealSet("test", images, lights / lights.sum(1, keepdims=True)), profile


def _cg():
    return [np.random.default_rng(5).random((160, 200, 3)).astype(np.float32)]   # linear float32: used as is


def _fake_sets(monkeypatch, calls):
    """g2r_set / upi_set that only record their inputs (the rows' logic, not the simulation)."""

    def g2r_set(views, profile, seed, **_):
        calls.append(("g2r", np.asarray(views), profile, seed))
        rng = np.random.default_rng(seed)
        return rng.random((len(views), 64, 64, 3)).astype(np.float32), rng.uniform(0.2, 0.5, (len(views), 3))

    def upi_set(views, seed):
        calls.append(("upi", np.asarray(views), None, seed))
        rng = np.random.default_rng(seed)
        return rng.random((len(views), 64, 64, 3)).astype(np.float32), rng.uniform(0.2, 0.5, (len(views), 3))

    monkeypatch.setattr(training_sets, "g2r_set", g2r_set)
    monkeypatch.setattr(training_sets, "upi_set", upi_set)


def test_the_rows_model_is_fitted_to_the_training_folds_only(monkeypatch):
    """The rows' 'cast' model reads the training folds' files only, once per (fold, seed), and no
    estimator chooses it."""
    real, profile = _real_set()
    index = {image.tobytes(): i for i, image in enumerate(real.images)}
    fitted_to = []
    original_candidate = content_rows.candidate_model

    def candidate(name, images, lights, views, prof):
        fitted_to.append((name, {index[image.tobytes()] for image in np.asarray(images)}))
        return original_candidate(name, images, lights, views, prof)

    def no_selection(*args, **kwargs):
        raise AssertionError("the rows' model is fitted, not chosen by an estimator")

    monkeypatch.setattr(content_rows, "candidate_model", candidate)
    monkeypatch.setattr(content_rows, "select_candidate", no_selection)
    monkeypatch.setattr(estimators, "train_estimator",
                        lambda name, x, y, seed=0: (lambda test: np.tile(y.mean(0), (len(test), 1))))
    _fake_sets(monkeypatch, [])
    result = experiment.illuminant_experiment(real, profile, _cg(), rows=("fitted", "upi_content"),
                                              estimators=("moments",), seeds=(0, 1), n=50, folds=2,
                                              illuminant_model="prior")
    tests = folds_of(len(real.images), 2, 0, groups=real.groups)
    assert len(fitted_to) == 4                                   # one per (fold, seed), shared by both rows
    for k, (name, seen) in enumerate(fitted_to):
        assert name == product.FITTED
        assert seen == set(range(len(real.images))) - set(tests[k % 2].tolist())
    assert sum("content model of the g2r_jax rows, seed" in note and "cast" in note for note in result.notes) == 4
    assert {row for row, _ in result.errors} == {"fitted", "upi_content"}


def test_the_benchmarks_selection_never_sees_the_test_fold(monkeypatch):
    """`fold_content_model` (benchmarks/content_model.py --families): every real image it reads
    (the thumbnails its candidates are fitted to, the lights fitted, the images its estimator is
    tested on) is in the training folds, and the inner third it validates on is held out."""
    real, profile = _real_set()
    index = {image.tobytes(): i for i, image in enumerate(real.images)}
    light_index = {light.tobytes(): i for i, light in enumerate(real.illuminants)}
    seen = {"validated": set(), "fitted": set(), "lights": set()}

    def indices(images):
        return {index[image.tobytes()] for image in np.asarray(images)}

    def train_estimator(name, images, lights, seed=0):
        def predict(test):
            seen["validated"] |= indices(test)
            return np.tile([1.0, 1.0, 1.0], (len(test), 1)) / np.sqrt(3)
        return predict

    original_candidate = content_rows.candidate_model
    selecting = [True]

    def candidate(name, images, lights, views, prof):
        if selecting[0]:
            seen["fitted"] |= indices(images)
        return original_candidate(name, images, lights, views, prof)

    def fit_lights(lights):
        seen["lights"] |= {light_index[np.asarray(light, np.float64).tobytes()] for light in lights}
        return profile

    monkeypatch.setattr(estimators, "train_estimator", train_estimator)
    monkeypatch.setattr(content_rows, "candidate_model", candidate)
    _fake_sets(monkeypatch, [])
    test = folds_of(len(real.images), 2, 0, groups=real.groups)[0]
    train = np.setdiff1d(np.arange(len(real.images)), test)
    views = training_sets.cg_views(_cg(), 30, 0)
    name, errors = content_rows.select_candidate(content_rows.CANDIDATES + ("cast",), real, train, views, profile,
                                                 fit_lights, seed=0, fold=0)
    assert name in errors and set(errors) == set(content_rows.CANDIDATES + ("cast",))
    assert seen["validated"] and seen["fitted"] and seen["lights"]
    assert not (seen["validated"] | seen["fitted"] | seen["lights"]) & set(test.tolist())
    assert not seen["validated"] & (seen["fitted"] | seen["lights"])   # the inner third is held out


def test_inner_split_keeps_files_with_the_same_pixels_together():
    train = np.arange(3, 15)
    groups = np.arange(15) // 2                                  # files 2k and 2k + 1 are copies
    inner, validate = content_rows.inner_split(train, groups, seed=0, fold=1)
    assert set(inner) | set(validate) == set(train) and not set(inner) & set(validate)
    assert not {groups[i] for i in inner} & {groups[i] for i in validate}


@pytest.mark.parametrize("by_default", [False, True])
def test_a_profiles_own_content_model_is_used_as_given(monkeypatch, by_default):
    from g2r_jax.content import apply, content_model
    from g2r_jax.profile.schema import replace

    real, profile = _real_set()
    model = content_model(0.35, source="test", apply_by_default=by_default)
    profile = replace(profile, content=model)
    calls = []
    _fake_sets(monkeypatch, calls)

    def no_selection(*args, **kwargs):
        raise AssertionError("the profile's own model must be used without a selection")

    monkeypatch.setattr(content_rows, "select_candidate", no_selection)
    monkeypatch.setattr(estimators, "train_estimator",
                        lambda name, x, y, seed=0: (lambda test: np.tile(y.mean(0), (len(test), 1))))
    result = experiment.illuminant_experiment(real, profile, _cg(), rows=("fitted", "upi_content"),
                                              estimators=("moments",), seeds=(0,), n=50, folds=2)
    views = training_sets.cg_views(_cg(), 50, 0)
    expected = np.asarray(apply(model, views))
    g2r_calls = [c for c in calls if c[0] == "g2r"]
    upi_calls = [c for c in calls if c[0] == "upi"]
    assert len(g2r_calls) == 2 and len(upi_calls) == 2             # one per fold
    for _, given, simulated_with, _ in g2r_calls:
        np.testing.assert_allclose(given, expected, atol=1e-6)     # adapted once, by the profile's model
        assert simulated_with.content is None                      # ... and not again in the simulation
    np.testing.assert_allclose(upi_calls[0][1], training_sets.linear_to_srgb_views(expected), atol=1e-6)
    assert not np.allclose(expected, views, atol=1e-3)
    assert any("used as given" in note and "0.35" in note for note in result.notes)
    assert any("carries it too" in note for note in result.notes) == by_default


def test_content_rows_are_not_default_and_an_unknown_row_is_refused_by_name(tmp_path):
    from g2r_jax.downstream import default_rows, run_check

    assert not set(experiment.CONTENT_ROWS) & set(default_rows(True))
    assert {"fitted", "fitted_no_content", "single"} <= set(default_rows(False))   # the product and its control
    assert default_rows(True, content_rows=True)[-1:] == ("upi_content",)
    assert set(experiment.CONTENT_ROWS) < set(content_rows.BUILDERS) <= set(experiment.ROWS)
    with pytest.raises(ValueError, match="'contnet'"):
        run_check([tmp_path], [tmp_path], rows=("fitted", "contnet"))   # before any file is read
    real, profile = _real_set()
    with pytest.raises(ValueError, match="contnet"):
        experiment.illuminant_experiment(real, profile, _cg(), rows=("contnet",), estimators=("moments",), n=50,
                                         folds=2)


@pytest.fixture(scope="module")
def camera_folders(tmp_path_factory):
    """12 DNGs of a NikonD40 (dead-leaves scenes under drawn lights) and 3 CG PNGs."""
    return write_camera_folders(tmp_path_factory.mktemp("content_rows"), 12, 3)


def test_the_flag_asks_run_check_for_the_content_rows(tmp_path, monkeypatch, capsys):
    from g2r_jax.cli import downstream
    from g2r_jax.downstream import check, default_rows

    asked = []

    def run_check(*args, rows=None, **kwargs):
        asked.append(rows)
        raise ValueError("stop here")

    monkeypatch.setattr(check, "run_check", run_check)
    (tmp_path / "in").mkdir()
    for flag in ((), ("--content-rows",)):
        status = downstream.main([str(a) for a in ("--measured", tmp_path / "in", "--cg", tmp_path / "in", "--report",
                                                   tmp_path / "r", "--profile", "NikonD40", "--quiet", *flag)])
        assert status == 2 and "stop here" in capsys.readouterr().err
    assert asked == [None, default_rows(True, content_rows=True)]


@pytest.mark.slow
def test_g2r_downstream_reports_the_content_rows(camera_folders, tmp_path, capsys):
    """End to end (about a minute on two cores: the DNGs are simulated, every row trained)."""
    from g2r_jax.cli import downstream

    dngs, cg = camera_folders
    report = tmp_path / "report"
    status = downstream.main([str(a) for a in ("--measured", dngs, "--cg", cg, "--report", report, "--content-rows",
                                               "--estimators", "moments", "--seeds", 1, "--n", 50, "--folds", 2,
                                               "--quiet")])
    out, err = capsys.readouterr()
    assert status == 0, err
    document = json.loads((report / "report.json").read_text())
    assert document["rows"][-1:] == ["upi_content"]
    for row in ("fitted", "fitted_no_content", "upi", "upi_content"):
        assert np.isfinite(document["summary"][f"{row}/moments"]["mean"])
    assert sum("content model of the g2r_jax rows, seed 0, fold" in note for note in document["notes"]) == 2
    page = (report / "report.md").read_text()
    assert experiment.ROWS["fitted"] in page and experiment.ROWS["upi_content"] in page
    assert "content model of the g2r_jax rows, seed 0, fold 1: cast" in page


@pytest.mark.slow
@pytest.mark.data
def test_the_library_rows_give_the_benchmarks_figures(shared_data, monkeypatch):
    """One implementation: `g2r-downstream`'s rows and benchmarks/content_model.py give the same
    per-image errors for the same seeds (Canon600D, 40 views, moments; about a minute)."""
    import importlib.util
    from pathlib import Path

    from PIL import Image

    from g2r_jax.runtime import compile_cache

    monkeypatch.setattr(compile_cache, "enable", lambda **_: None)   # leave the test process as it is
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "content_model.py"
    spec = importlib.util.spec_from_file_location("benchmark_content_model", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    ran = bench.run_camera(("Canon600D", ("moments",), (0,), 40, (), content_rows.SELECTION_ESTIMATOR,
                            product.FITTED))
    frames = [np.asarray(Image.open(p).convert("RGB")) for p in sorted((shared_data / "cg" / "carla").glob("*.png"))]
    real = real_sets.load_nus(shared_data / "estimation" / "nus" / "Canon600D.npz")
    result = experiment.illuminant_experiment(real, bench.camera_profile("Canon600D"), frames,
                                              rows=("fitted_no_content", "fitted", "upi", "upi_content", "real"),
                                              estimators=("moments",), seeds=(0,), n=40, folds=3)
    for row, benchmark_row in (("fitted_no_content", "fitted"), ("fitted", "fitted+content"), ("upi", "upi"),
                               ("upi_content", "upi+content"), ("real", "real")):
        np.testing.assert_allclose(result.errors[(row, "moments")][0], ran["errors"][f"{benchmark_row}/moments"][0],
                                   rtol=1e-6, err_msg=row)
    assert [c["family"] for c in ran["chosen"]] == [product.FITTED] * 3
    assert sum("content model of the g2r_jax rows, seed 0, fold" in note for note in result.notes) == 3


def test_a_profile_that_applies_its_model_keeps_it_off_the_real_content_controls(monkeypatch):
    """A fitted profile applies its 'cast' model by default: the CG rows carry it ('fitted' on
    views adapted once, 'shipped' in the simulation), the controls (real scenes made RAW again)
    never do."""
    from g2r_jax.content import content_model
    from g2r_jax.profile.schema import replace

    real, profile = _real_set()
    profile = replace(profile, content=content_model(cast_scale=0.0, family="cast", apply_by_default=True))
    calls = []
    _fake_sets(monkeypatch, calls)
    monkeypatch.setattr(estimators, "train_estimator",
                        lambda name, x, y, seed=0: (lambda test: np.tile(y.mean(0), (len(test), 1))))
    rows = ("fitted", "shipped", "real_own_light", "real_other_light", "real_profile_light")
    experiment.illuminant_experiment(real, profile, _cg(), rows=rows, estimators=("moments",), seeds=(0,), n=50,
                                     folds=2, illuminant_model="prior")
    g2r_calls = [c for c in calls if c[0] == "g2r"]
    assert len(g2r_calls) == 2 * len(rows) - 1                    # one set per row and fold; 'shipped' once per seed
    with_model = [c for c in g2r_calls if c[2].content is not None]
    assert len(with_model) == 1 and with_model[0][2].content.family == "cast"    # the 'shipped' row
    views = training_sets.cg_views(_cg(), 50, 0)
    expected = np.asarray(product.adapted_views(profile.content, views))
    assert not np.allclose(expected, views, atol=1e-3)
    adapted = [c for c in g2r_calls if c[1].shape == views.shape and np.allclose(c[1], expected, atol=1e-5)]
    assert len(adapted) == 2                                      # the 'fitted' row, once per fold


def test_rows_trained_side_by_side_give_the_same_errors():
    """`workers` only changes the wall time: two threads and one give the same per-image errors
    (real simulation and estimator, a small set)."""
    real, profile = _real_set()
    kwargs = dict(rows=("upi", "fitted", "fitted_no_content", "single", "real", "real_profile_light", "upi_content"),
                  estimators=("moments", "histogram"), seeds=(0,), n=50, folds=2, illuminant_model="prior")
    one = experiment.illuminant_experiment(real, profile, _cg(), workers=1, **kwargs)
    two = experiment.illuminant_experiment(real, profile, _cg(), workers=3, **kwargs)
    assert one.errors.keys() == two.errors.keys()
    for key in one.errors:
        np.testing.assert_array_equal(one.errors[key][0], two.errors[key][0], err_msg=str(key))
