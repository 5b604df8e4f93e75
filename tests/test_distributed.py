"""Many devices and many machines: sharded batches and the Ray engine give the same bytes.

The sharding test runs in a subprocess, because XLA_FLAGS=--xla_force_host_platform_device_count
must be set before JAX initialises (this process has already started JAX with one CPU device).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from PIL import Image

SHARDING_CHECK = textwrap.dedent("""
    import jax, jax.numpy as jnp, numpy as np
    from g2r_jax.profile.schema import load_profile
    from g2r_jax.pipeline import unprocess, unprocess_batch
    from g2r_jax.batch.distributed import unprocess_sharded

    assert len(jax.local_devices()) == 4, jax.local_devices()
    profile = load_profile("s20fe_night")
    rng = np.random.default_rng(3)
    # 6: padded to 8, two images per device. Each case compiles three programs, so the option
    # set varies with the batch rather than across it.
    for batch, options in ((8, {}), (6, {"noise": False, "transfer": "gamma2.2"})):
        images = jnp.asarray(rng.integers(0, 256, (batch, 24, 36, 3), dtype=np.uint8))
        keys = jax.random.split(jax.random.PRNGKey(11), batch)
        mosaics, meta = unprocess_sharded(keys, images, profile, **options)
        assert mosaics.shape == (batch, 24, 36) and mosaics.dtype == jnp.uint16
        if batch == 8:
            assert len(mosaics.sharding.device_set) == 4, mosaics.sharding
        reference, reference_meta = jax.jit(lambda k, im: unprocess_batch(k, im, profile, **options))(keys, images)
        np.testing.assert_array_equal(np.asarray(mosaics), np.asarray(reference))
        for name in reference_meta:
            np.testing.assert_array_equal(np.asarray(meta[name]), np.asarray(reference_meta[name]), err_msg=name)
        single, _ = jax.jit(lambda k, im: unprocess(k, im, profile, **options))(keys[1], images[1])
        np.testing.assert_array_equal(np.asarray(mosaics[1]), np.asarray(single))
    neutrals = jnp.asarray(rng.uniform(0.4, 0.9, (8, 3)), jnp.float32).at[:, 1].set(1.0)
    images = jnp.asarray(rng.integers(0, 256, (8, 24, 36, 3), dtype=np.uint8))
    keys = jax.random.split(jax.random.PRNGKey(12), 8)
    sharded, meta = unprocess_sharded(keys, images, profile, neutral=neutrals, iso=800.0)
    reference, _ = jax.jit(lambda k, im, n: unprocess_batch(k, im, profile, neutral=n, iso=800.0))(keys, images, neutrals)
    np.testing.assert_array_equal(np.asarray(sharded), np.asarray(reference))
    np.testing.assert_allclose(np.asarray(meta["neutral"]), np.asarray(neutrals), rtol=1e-6)
    print("sharding ok")
""")


def test_batch_sharded_over_four_cpu_devices_equals_unsharded_bit_for_bit():
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4", JAX_PLATFORMS="cpu")
    result = subprocess.run([sys.executable, "-c", SHARDING_CHECK], env=env, capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "sharding ok" in result.stdout


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _write_inputs(folder):
    folder.mkdir()
    rng = np.random.default_rng(0)
    for index in range(7):
        shape = (24, 32) if index != 4 else (20, 30)          # one odd-one-out size
        Image.fromarray(rng.integers(0, 256, shape + (3,), dtype=np.uint8)).save(folder / f"scene_{index}.png")
    return sorted(folder.glob("*.png"))


@pytest.mark.slow
def test_ray_engine_writes_the_same_bytes_as_the_local_engine(tmp_path):
    ray = pytest.importorskip("ray")
    from g2r_jax.batch.conversion import ConvertOptions, convert_files
    from g2r_jax.batch.distributed import convert_files_ray
    from g2r_jax.profile.schema import load_profile

    files = _write_inputs(tmp_path / "in")
    neutrals = np.tile([0.6, 1.0, 0.8], (len(files), 1)) * np.linspace(0.9, 1.1, len(files))[:, None]
    neutrals[:, 1] = 1.0
    for name, rows in (("sampled", None), ("given", neutrals)):
        options = ConvertOptions(seed=5, batch_size=4, progress=False)
        local = convert_files(files, load_profile("s20fe_night"), tmp_path / f"local_{name}", neutrals=rows,
                              options=options)
        ray.init(num_cpus=2, include_dashboard=False, ignore_reinit_error=True)
        try:
            distributed = convert_files_ray(files, "s20fe_night", tmp_path / f"ray_{name}", neutrals=rows,
                                            options=options, files_per_task=3)   # chunks cut across batches
        finally:
            ray.shutdown()
        assert local.ok and distributed.ok, (local.errors, distributed.errors)
        for path in files:
            a, b = tmp_path / f"local_{name}" / f"{path.stem}.dng", tmp_path / f"ray_{name}" / f"{path.stem}.dng"
            assert _digest(a) == _digest(b), path.name
        strip = lambda records: [{k: v for k, v in r.items() if k != "output"} for r in records]
        assert strip(local.records) == strip(distributed.records)
        manifest = [json.loads(line) for line in (tmp_path / f"ray_{name}" / "manifest.jsonl").read_text().splitlines()]
        assert [r["input"] for r in manifest] == [str(p) for p in files]


def test_ray_engine_reports_a_missing_ray_clearly(monkeypatch):
    import builtins

    from g2r_jax.batch import distributed

    real_import = builtins.__import__

    def no_ray(name, *args, **kwargs):
        if name == "ray" or name.startswith("ray."):
            raise ImportError("No module named 'ray'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ray)
    with pytest.raises(ImportError, match=r"pip install 'g2r_jax\[ray\]'"):
        distributed.convert_files_ray([], "Canon600D", "unused")


def test_unprocess_batch_gives_the_same_bytes_whatever_the_batch():
    import jax
    import jax.numpy as jnp

    from g2r_jax.profile.schema import load_profile
    from g2r_jax.pipeline import unprocess, unprocess_batch

    profile = load_profile("gopro_hero6")
    images = jnp.asarray(np.random.default_rng(2).integers(0, 256, (5, 16, 24, 3), dtype=np.uint8))
    keys = jax.random.split(jax.random.PRNGKey(9), 5)
    batch = jax.jit(lambda k, im: unprocess_batch(k, im, profile)[0])
    everything = np.asarray(batch(keys, images))
    for size in (1, 2, 3):
        for start in (0, 5 - size):
            np.testing.assert_array_equal(np.asarray(batch(keys[start:start + size], images[start:start + size])),
                                          everything[start:start + size])
    single = jax.jit(lambda k, im: unprocess(k, im, profile)[0])
    for i in range(5):
        np.testing.assert_array_equal(np.asarray(single(keys[i], images[i])), everything[i])


@pytest.mark.slow
def test_ray_engine_converts_a_profile_edited_in_memory_as_it_is(tmp_path):
    """g2r-convert --engine ray used to refuse --content-model / --no-content-model: its tasks loaded
    the profile file as it was. Now the driver's profile object goes to the tasks: a content model
    switched on in memory gives the local engine's bytes, and differs from the file's profile."""
    ray = pytest.importorskip("ray")
    from g2r_jax.batch.conversion import ConvertOptions, convert_files
    from g2r_jax.batch.distributed import convert_files_ray
    from g2r_jax.content import content_model
    from g2r_jax.profile.schema import load_profile, replace

    files = _write_inputs(tmp_path / "in")[:4]
    edited = replace(load_profile("Canon600D"), content=content_model(0.4, apply_by_default=True))
    options = ConvertOptions(seed=2, batch_size=2, progress=False)
    local = convert_files(files, edited, tmp_path / "local", options=options)
    ray.init(num_cpus=2, include_dashboard=False, ignore_reinit_error=True)
    try:
        distributed = convert_files_ray(files, edited, tmp_path / "ray", options=options, files_per_task=2)
        as_file = convert_files_ray(files, "Canon600D", tmp_path / "file", options=options, files_per_task=2)
    finally:
        ray.shutdown()
    assert local.ok and distributed.ok and as_file.ok, (local.errors, distributed.errors, as_file.errors)
    for path in files:
        name = f"{path.stem}.dng"
        assert _digest(tmp_path / "local" / name) == _digest(tmp_path / "ray" / name), path.name
        assert _digest(tmp_path / "file" / name) != _digest(tmp_path / "ray" / name), path.name
