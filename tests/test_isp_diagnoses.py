"""The ISP benchmark's diagnoses (benchmarks/isp_diagnoses.py): the plain variant is the task's own
control, the levels and the fill do what they say."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import g2r_jax
from g2r_jax.downstream.base.real_sets import RealSet
from g2r_jax.downstream.isp import pairs, task

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import isp_diagnoses  # noqa: E402


def _row_sets(count: int = 6):
    profile = g2r_jax.load_profile("NikonD40")
    rng = np.random.default_rng(0)
    images = rng.uniform(0.05, 0.9, (count, 64, 64, 3)).astype(np.float32)
    images[:, 10:15, 20:27] = 0.0
    lights = np.c_[rng.uniform(0.4, 0.7, count), np.ones(count), rng.uniform(0.5, 0.8, count)]
    real = RealSet(name="test", images=images, illuminants=lights)
    masks = pairs.thumbnail_masks(images)
    real, real_pairs, _, _ = task._real_pairs(real, pairs.thumbnail_sources(images, lights, profile), 64, 3, masks)
    return task._RowSets(real, real_pairs, profile, profile, np.zeros((1, 64, 64, 3), np.float32), n=8, size=64,
                         view_size=32, illuminant_model="auto", single_light="auto", lights=None, masks=real_pairs[2])


def test_the_plain_variant_builds_the_tasks_own_control(monkeypatch):
    monkeypatch.setattr(task._RowSets, "build", task._RowSets.build)     # restored after the test
    train = np.arange(6)
    own = _row_sets().build("real_profile_light", train, 0, 1)
    isp_diagnoses.control_variant("drawn", "drawn")
    plain = _row_sets().build("real_profile_light", train, 0, 1)
    assert all(np.array_equal(a, b) for a, b in zip(own, plain))
    isp_diagnoses.control_variant("own", "own")
    sets = _row_sets()
    packed, _, masks = sets.build("real_profile_light", train, 0, 1)
    levels = isp_diagnoses.top_levels(packed[:6], masks[:6])
    np.testing.assert_allclose(levels, isp_diagnoses.top_levels(sets.pairs[0][train], masks[:6]), rtol=0.05)
    assert not np.allclose(packed, plain[0])


def test_levels_and_fill():
    packed = np.zeros((2, 10, 10, 4), np.float32)
    packed[0, ..., 2] = np.linspace(0, 1, 100).reshape(10, 10)
    levels = isp_diagnoses.top_levels(packed)
    assert abs(levels[0] - 0.99) < 0.01 and levels[1] == 0
    images = np.full((1, 4, 4, 3), 0.5, np.float32)
    images[0, 0, 0] = 0.0
    images[0, 1, 1] = [0.1, 0.2, 0.3]
    filled = isp_diagnoses.fill_missing(images)
    np.testing.assert_allclose(filled[0, 0, 0], images[0].reshape(-1, 3)[1:].mean(0))
    assert images[0, 0, 0].max() == 0      # the input is not modified


def test_joint_scenes_build_the_fitted_rows_pairs(monkeypatch):
    monkeypatch.setattr(task._RowSets, "build", task._RowSets.build)     # restored after the test
    isp_diagnoses.joint_scenes()
    sets = _row_sets()
    sets.cg = np.random.default_rng(1).uniform(0.05, 1.0, (4, 64, 64, 3)).astype(np.float32)
    packed, targets = sets.build("fitted", np.arange(6), 0, 0)
    assert packed.shape == (8, 32, 32, 4) and targets.shape == (8, 64, 64, 3)
    assert np.all(np.isfinite(packed)) and packed.max() > 0


def test_joint_views_take_the_drawn_files_cast():
    sets = _row_sets()
    sets.cg = np.random.default_rng(1).uniform(0.05, 1.0, (4, 64, 64, 3)).astype(np.float32)
    adapted, lights, casts, pick = isp_diagnoses.joint_views(sets, np.arange(6), 0, 0)
    means = adapted.reshape(len(adapted), -1, 3).mean(1)
    chroma = lambda c: np.log(c[:, [0, 2]] / c[:, 1:2])
    np.testing.assert_allclose(chroma(means), chroma(casts[pick]), atol=0.05)
    assert np.array_equal(lights, np.asarray(sets.real.illuminants, np.float64)[pick])


def test_the_inner_set_never_holds_the_first_outer_test_fold():
    import downstream_isp_nus

    from g2r_jax.measure import folds_of

    rng = np.random.default_rng(2)
    real = RealSet(name="t", images=rng.random((30, 64, 64, 3)).astype(np.float32), illuminants=np.ones((30, 3)) / 3,
                   files=tuple(f"f{i}" for i in range(30)))
    inner = downstream_isp_nus.inner_set(real)
    first = set(folds_of(30, 3, 0)[0].tolist())
    assert len(inner.images) == 30 - len(first) and not first & {int(f[1:]) for f in inner.files}
