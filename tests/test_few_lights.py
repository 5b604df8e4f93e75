"""benchmarks/few_lights.py's leave-one-dataset-out rows: `auto-gs` (the default with every NUS
camera out of its pool) and the content `cg-scenes` (the scenes model of the same files whose
lights a row uses)."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import few_lights as fl  # noqa: E402

CAMERA = "NikonD40"   # a NUS camera with a shipped profile: no data needed for its lights
LIGHTS = np.array([[0.50, 1.0, 0.62], [0.46, 1.0, 0.66], [0.52, 1.0, 0.60], [0.62, 1.0, 0.52], [0.45, 1.0, 0.67],
                   [0.75, 1.0, 0.42], [0.47, 1.0, 0.65], [0.55, 1.0, 0.57], [0.58, 1.0, 0.55], [0.68, 1.0, 0.47],
                   [0.44, 1.0, 0.68]])


@pytest.mark.slow
def test_auto_gs_is_the_gehler_shi_pool_below_ten_lights_and_auto_from_ten():
    profile = fl.camera_profile(CAMERA)
    for n in (0, 1):
        gs = fl.fingerprint(fl.model_for("auto-gs", CAMERA, profile, LIGHTS[:n]))
        assert gs == fl.fingerprint(fl.model_for("pooled-gs", CAMERA, profile, LIGHTS[:n]))
        assert gs != fl.fingerprint(fl.model_for("auto", CAMERA, profile, LIGHTS[:n]))   # the NUS pool differs
    many = LIGHTS[:10]
    assert (fl.fingerprint(fl.model_for("auto-gs", CAMERA, profile, many))
            == fl.fingerprint(fl.model_for("auto", CAMERA, profile, many))
            != fl.fingerprint(fl.model_for("pooled-gs", CAMERA, profile, many)))


def test_the_files_of_a_count_are_drawn_once_for_lights_and_content():
    drawn = fl.subset_indices(40, 5, 3, seed=1, fold=2)
    assert len(drawn) == 3 and all(len(d) == 5 == len(set(d)) for d in drawn)
    assert not all(np.array_equal(drawn[0], d) for d in drawn[1:])      # draws differ
    np.testing.assert_array_equal(fl.subset_indices(40, 5, 3, seed=1, fold=2)[1], drawn[1])   # and repeat
    for count in (None, 40, 60):
        (everything,) = fl.subset_indices(40, count, 3, seed=0, fold=0)
        np.testing.assert_array_equal(everything, np.arange(40))


def test_the_few_light_variants_are_models_and_malformed_ones_are_not():
    assert all(fl._is_variant(v) for v in ("near:24", "wide:2", "n0:20", "near:0.5"))
    assert not any(fl._is_variant(v) for v in ("near", "near:", "near:x", "wide:-1", "far:2", "auto-gs"))


@pytest.mark.slow
def test_a_few_light_variant_row_is_the_energy_lodo_model_with_every_nus_camera_out():
    from g2r_jax.illuminants.distributions import neutral_to_chromaticity

    profile = fl.camera_profile(CAMERA)
    row = fl.model_for("near:24", CAMERA, profile, LIGHTS[:5])
    variant = fl._lodo_variant("near:24", neutral_to_chromaticity(LIGHTS[:5]), profile.colour, fl.CAMERAS)
    np.testing.assert_allclose(np.asarray(row.illuminants.means), np.asarray(variant.means), rtol=1e-6)
    assert fl.fingerprint(row) != fl.fingerprint(fl.model_for("auto-gs", CAMERA, profile, LIGHTS[:5]))


def test_unknown_names_are_refused_before_any_work(capsys, tmp_path):
    out = tmp_path / "x.jsonl"
    for option, value in (("--content", "cg,cg-scene"), ("--estimators", "cnn,histogramm"), ("--models", "auto-gz"),
                          ("--models", "near:x")):
        assert fl.main([option, value, "--cameras", CAMERA, "--out", str(out)]) == 2
        assert f"unknown {option} {value.split(',')[-1]};" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.data
@pytest.mark.slow
def test_cg_scenes_fits_the_rows_files_with_the_camera_out_of_the_prior(shared_data):
    from g2r_jax.content import fitting, prior
    from g2r_jax.downstream.base import real_sets
    from g2r_jax.downstream.base.product import candidate_model

    profile = fl.camera_profile(CAMERA)
    real = real_sets.load_nus(shared_data / "estimation" / "nus" / f"{CAMERA}.npz")
    before = dict(prior.REAL_SCENES["medians"])
    none = fl.scenes_content(CAMERA, profile, real.images[:0], real.illuminants[:0], None)
    shipped = fl.shipped_content_model(CAMERA, profile.colour)
    assert none.family == "cast"
    np.testing.assert_allclose(np.asarray(none.cast_target), np.asarray(shipped.cast_target))
    files = np.arange(0, 60, 4)
    model = fl.scenes_content(CAMERA, profile, real.images[files], real.illuminants[files], None)
    assert prior.REAL_SCENES["medians"] == before                        # the product's prior is back
    assert model.family == "scenes" and dict(model.target)["scenes"] <= len(files)
    without = prior.real_scenes_without(shared_data, CAMERA)
    product = candidate_model("scenes", real.images[files], real.illuminants[files], None, profile)
    for name in ("cast_red", "cast_blue"):
        weight = fitting.files_weight(name, len(files))
        # the cast centre: the files' median shrunk toward the prior without the camera, not the product's prior
        shift = dict(model.target)[name] - dict(product.target)[name]
        np.testing.assert_allclose(shift, (1 - weight) * (without[name] - before[name]), atol=1e-9)
        assert abs(without[name] - before[name]) > 1e-4
