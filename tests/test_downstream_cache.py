"""The store of finished downstream trainings (issue 52): a second run on the same inputs trains
nothing and reports the same figures; a run that adds a row trains only that row; `--no-cache`
trains everything; a damaged entry is retrained; the store keeps to its cap."""

from __future__ import annotations

import json

import numpy as np
import pytest
from downstream_helpers import write_camera_folders

from g2r_jax.cli import downstream
from g2r_jax.downstream.base.cache import DownstreamCache, key_of


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    return write_camera_folders(tmp_path_factory.mktemp("cache"), 12, 3)


def _check(folders, report, *extra):
    dngs, cg = folders
    status = downstream.main([str(a) for a in ("--measured", dngs, "--cg", cg, "--report", report, "--profile",
                                                "NikonD40", "--estimators", "moments", "--seeds", 1, "--n", 50,
                                                "--folds", 2, "--quiet", *extra)])
    assert status == 0
    return json.loads((report / "report.json").read_text())


def test_a_second_run_reuses_every_training_and_reports_the_same(folders, tmp_path):
    first = _check(folders, tmp_path / "a")
    again = _check(folders, tmp_path / "b")
    assert first["cache"]["reused"] == 0 and first["cache"]["trained"] > 0
    assert again["cache"] == {**first["cache"], "reused": first["cache"]["trained"], "trained": 0}
    for key, value in first["summary"].items():
        assert again["summary"][key]["mean"] == pytest.approx(value["mean"], abs=1e-12), key
    assert "reused" in (tmp_path / "b" / "report.md").read_text()
    off = _check(folders, tmp_path / "c", "--no-cache")
    assert "cache" not in off


def test_a_run_with_another_row_trains_only_that_row(folders, tmp_path):
    first = _check(folders, tmp_path / "a")
    more = _check(folders, tmp_path / "b", "--content-rows")
    folds = 2
    assert more["cache"]["reused"] == first["cache"]["trained"]
    assert more["cache"]["trained"] == folds               # upi_content x moments x one seed


def test_damaged_entries_are_retrained_and_the_store_keeps_its_cap(tmp_path):
    cache = DownstreamCache(tmp_path / "store", cap_bytes=3000)
    key = key_of("unit", np.arange(3))
    cache.put(key, {"estimates": np.ones((4, 3))})
    assert np.array_equal(cache.get(key)["estimates"], np.ones((4, 3))) and cache.hits == 1
    (tmp_path / "store" / f"{key}.npz").write_bytes(b"not an npz")
    assert cache.get(key) is None and not (tmp_path / "store" / f"{key}.npz").exists()
    for i in range(10):
        cache.put(key_of("unit", i), {"estimates": np.zeros((20, 3))})
    assert sum(p.stat().st_size for p in (tmp_path / "store").glob("*.npz")) <= 3000
    assert cache.get(key_of("unit", 9)) is not None            # the newest kept, the oldest gone
    assert cache.get(key_of("unit", 0)) is None
    assert key_of("a", np.zeros(3)) != key_of("a", np.zeros(3, np.float32))


def test_the_code_digest_covers_the_whole_package():
    """`code_digest` reads every source file of `g2r_jax` (a changed line anywhere retrains), not
    only the sub-package `cache` sits in (issue 52 moved it to `downstream/base/`)."""
    import hashlib
    from pathlib import Path

    import g2r_jax
    from g2r_jax.downstream.base.cache import code_digest

    root = Path(g2r_jax.__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    assert code_digest() == digest.hexdigest()

def test_the_isp_task_reuses_its_stored_networks(monkeypatch, tmp_path):
    """A second ISP run on the same inputs trains no UNet and gives the same measures and figure."""
    import g2r_jax
    from g2r_jax.downstream.isp import net, task
    from test_downstream_isp import _sources

    from g2r_jax.downstream.base.real_sets import RealSet

    profile = g2r_jax.load_profile("NikonD40")
    sources, images, lights = _sources(profile, 6)
    real = RealSet(name="tiny", images=images, illuminants=lights / lights.sum(1, keepdims=True))
    cg = [(np.random.default_rng(k).random((40, 48, 3)) * 255).astype(np.uint8) for k in range(2)]
    training = net.IspTraining(steps=2, steps_per_round=2, batch=2, width=2)
    trained = []
    original = net.train_many
    monkeypatch.setattr(net, "train_many", lambda sets, *a, **k: trained.append(len(sets)) or original(sets, *a, **k))
    cache = DownstreamCache(tmp_path / "store")
    run = lambda rows: task.run_isp_task(real, profile, cg, rows=rows, seeds=(0,), n=4, dngs=sources, training=training,
                                         cache=cache)
    first = run(("upi", "real"))
    assert sum(trained) == 6 and cache.hits == 0
    again = run(("upi", "real"))
    assert sum(trained) == 6 and cache.hits == 6
    for key in first.metrics:
        np.testing.assert_array_equal(first.metrics[key][0], again.metrics[key][0])
    np.testing.assert_array_equal(first.examples["predicted"]["real"], again.examples["predicted"]["real"])
    run(("upi", "real", "fitted"))
    assert sum(trained) == 9                       # only the new row's three folds


def test_the_burst_check_reuses_its_stored_denoisers(monkeypatch, tmp_path):
    import g2r_jax
    from g2r_jax.downstream.denoising import burst_check, bursts
    from g2r_jax.downstream.denoising.denoiser import DenoiserTraining

    profile = g2r_jax.load_profile("s20fe_night")
    bursts.write_synthetic_burst(tmp_path / "burst", profile, n_frames=6, height=48, width=64, iso=1600, seed=3)
    burst = bursts.read_burst(tmp_path / "burst")
    trained = []
    original = burst_check._train_row
    monkeypatch.setattr(burst_check, "_train_row", lambda *a, **k: trained.append(1) or original(*a, **k))
    cache = DownstreamCache(tmp_path / "store")
    run = lambda: burst_check.run_burst_check(burst, profile, rows=("fitted", "real"), contents=("scene",), seeds=(0,),
                                              steps=None, max_steps=4, training=DenoiserTraining(batch=2, steps_per_round=2),
                                              cache=cache)
    first = run()
    count = len(trained)
    again = run()
    assert count > 0 and len(trained) == count and first.psnr == again.psnr and first.steps == again.steps
