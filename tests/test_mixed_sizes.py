"""Mixed image sizes: zero-padding to a bucket shape gives the bytes of the unpadded image."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.profile import schema as pm
from g2r_jax import sensor
from g2r_jax.batch.conversion import ConvertOptions, convert_files, plan_buckets
from g2r_jax.pipeline import unprocess_batch


def _profile_with_every_effect():
    profile = pm.load_profile("Canon600D")
    effects = sensor.SensorEffects(
        black_pedestal=jnp.array([1.0, 0.0, 2.0, 0.5]), clip_level=jnp.asarray(0.97),
        channel_gain=jnp.array([1.0, 1.02, 0.98, 1.0]), shading=jnp.array([[-0.3, 0.05]] * 4),
        defect_rows=jnp.array([3, 9], jnp.int32), defect_cols=jnp.array([5, 1], jnp.int32),
        defect_values=jnp.array([1.0, 0.0]), row_noise_std=jnp.asarray(0.002), column_noise_std=jnp.asarray(0.001))
    return pm.replace(profile, effects=effects)


def test_padded_batch_gives_each_image_its_unpadded_bytes():
    profile = _profile_with_every_effect()
    rng = np.random.default_rng(0)
    sizes = [(10, 14), (16, 24), (12, 8)]
    images = [rng.integers(0, 256, size + (3,), dtype=np.uint8) for size in sizes]
    keys = jax.random.split(jax.random.PRNGKey(1), 3)
    batch = jax.jit(lambda k, im, v: unprocess_batch(k, im, profile, valid_shapes=v, return_clean=True))
    padded = np.zeros((3, 16, 24, 3), np.uint8)
    for j, image in enumerate(images):
        padded[j, :image.shape[0], :image.shape[1]] = image
    noisy, clean, _ = batch(keys, jnp.asarray(padded), jnp.asarray(sizes, jnp.int32))
    for j, image in enumerate(images):
        h, w = image.shape[:2]
        alone_noisy, alone_clean, _ = batch(keys[j:j + 1], jnp.asarray(image[None]), jnp.asarray([[h, w]], jnp.int32))
        np.testing.assert_array_equal(np.asarray(noisy[j, :h, :w]), np.asarray(alone_noisy[0]))
        np.testing.assert_array_equal(np.asarray(clean[j, :h, :w]), np.asarray(alone_clean[0]))
    assert np.any(np.asarray(noisy) != np.asarray(clean))


def test_buckets_hold_many_sizes_within_the_padding_factor():
    sizes = [(3024, 4032), (3000, 4000), (2160, 3840), (1080, 1920), (720, 1280), (2448, 3264)]
    buckets = plan_buckets(sizes)
    assert len(buckets) < len(sizes)
    for h, w in sizes:
        assert any(bh >= h and bw >= w and bh * bw <= 4 * h * w for bh, bw in buckets)


def test_a_file_alone_and_in_a_mixed_folder_gives_the_same_bytes(tmp_path):
    from PIL import Image

    rng = np.random.default_rng(3)
    folder = tmp_path / "mixed"
    folder.mkdir()
    for name, (h, w) in {"a": (40, 60), "b": (34, 50), "c": (48, 64), "d": (40, 60)}.items():
        Image.fromarray(rng.integers(0, 256, (h, w, 3), dtype=np.uint8)).save(folder / f"{name}.png")
    options = ConvertOptions(progress=False, batch_size=3)
    files = sorted(folder.glob("*.png"))
    mixed = convert_files(files, pm.load_profile("Canon600D"), tmp_path / "out_mixed", options=options)
    assert mixed.ok
    for path in files:
        alone = convert_files([path], pm.load_profile("Canon600D"), tmp_path / f"out_{path.stem}", options=options)
        assert alone.ok
        assert (tmp_path / f"out_{path.stem}" / f"{path.stem}.dng").read_bytes() == \
            (tmp_path / "out_mixed" / f"{path.stem}.dng").read_bytes()


def test_fewer_files_than_the_batch_size_are_not_padded_to_a_full_batch(tmp_path, monkeypatch):
    """One file is converted in a batch of one (a batch of four would compute four frames), and its
    bytes are those of the same file converted among others."""
    from PIL import Image

    from g2r_jax.batch import conversion

    calls = []
    original = conversion._batched_unprocess

    def recording(*args, **kwargs):
        program = original(*args, **kwargs)
        return lambda keys, images, *rest: (calls.append(images.shape[0]), program(keys, images, *rest))[1]

    monkeypatch.setattr(conversion, "_batched_unprocess", recording)
    folder = tmp_path / "in"
    folder.mkdir()
    rng = np.random.default_rng(5)
    for name in ("a", "b", "c", "d", "e"):
        Image.fromarray(rng.integers(0, 256, (16, 24, 3), dtype=np.uint8)).save(folder / f"{name}.png")
    profile = pm.load_profile("gopro_hero6")
    convert_files([folder / "c.png"], profile, tmp_path / "alone", options=ConvertOptions(progress=False))
    assert calls == [1]
    convert_files(sorted(folder.iterdir()), profile, tmp_path / "all", options=ConvertOptions(progress=False))
    assert calls[1:] == [4, 4]
    assert (tmp_path / "alone" / "c.dng").read_bytes() == (tmp_path / "all" / "c.dng").read_bytes()


def test_the_keys_of_a_batch_are_each_files_own_key():
    """`file_keys` (one compiled program) gives `file_key` of every name, 64-bit seeds included."""
    from g2r_jax.batch.conversion import file_key, file_keys

    names = ["0001.png", "sceneA/0001.png", "é.exr", ""]
    for seed in (0, 7, 2**40 + 3, -5):
        expected = np.stack([np.asarray(file_key(seed, name)) for name in names])
        np.testing.assert_array_equal(np.asarray(file_keys(seed, names)), expected)


def test_the_first_program_is_compiled_ahead_only_for_a_credible_header(tmp_path, monkeypatch):
    """A good first PNG has its program prepared while it decodes; a PNG whose header claims rows
    its data cannot hold (refused once decoded) has nothing compiled for it, so its refusal is
    not kept waiting by a compilation for an 8000 x 8000 batch."""
    import struct
    import zlib

    from PIL import Image

    from g2r_jax.batch import conversion

    prepared = []
    original = conversion._batched_unprocess

    def recording(*args, **kwargs):
        program = original(*args, **kwargs)
        call = lambda *arguments: program(*arguments)
        call.prepare = lambda keys, images, *rest: (prepared.append(images.shape), program.prepare(keys, images, *rest))
        return call

    monkeypatch.setattr(conversion, "_batched_unprocess", recording)
    Image.fromarray(np.random.default_rng(6).integers(0, 256, (20, 30, 3), dtype=np.uint8)).save(tmp_path / "good.png")
    profile = pm.load_profile("gopro_hero6")
    convert_files([tmp_path / "good.png"], profile, tmp_path / "out", options=ConvertOptions(progress=False))
    assert prepared == [(1, 20, 30, 3)]
    chunk = lambda kind, data: struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    liar = tmp_path / "liar.png"
    liar.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 8000, 8000, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(bytes(10 * (1 + 3 * 8000)), 9)) + chunk(b"IEND", b""))
    result = convert_files([liar], profile, tmp_path / "out2", options=ConvertOptions(progress=False))
    assert result.errors and "truncated" in result.errors[0]
    assert prepared == [(1, 20, 30, 3)]
