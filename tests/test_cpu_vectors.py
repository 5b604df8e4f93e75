"""`g2r_jax.cpu_vectors`: when 512-bit CPU vectors are requested, and that the width does not
change a single output byte (the pixel loop is element-wise per lane)."""

import os
import subprocess
import sys

AVX512 = "processor\t: 0\nflags\t\t: fpu sse2 avx2 avx512f avx512bw\n"
AVX2 = "processor\t: 0\nflags\t\t: fpu sse2 avx2 fma\n"


def test_the_flag_is_added_only_where_it_helps_and_no_choice_is_overridden(monkeypatch):
    from g2r_jax.runtime import cpu_vectors

    monkeypatch.delenv(cpu_vectors.OPT_OUT, raising=False)
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x")
    assert cpu_vectors.prefer_wide_vectors(AVX512)
    assert os.environ["XLA_FLAGS"] == "--xla_dump_to=/tmp/x --xla_cpu_prefer_vector_width=512"
    assert not cpu_vectors.prefer_wide_vectors(AVX512)            # once only
    monkeypatch.setenv("XLA_FLAGS", "")
    assert not cpu_vectors.prefer_wide_vectors(AVX2)
    assert os.environ["XLA_FLAGS"] == ""
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_prefer_vector_width=256")
    assert not cpu_vectors.prefer_wide_vectors(AVX512)
    monkeypatch.setenv("XLA_FLAGS", "")
    monkeypatch.setenv(cpu_vectors.OPT_OUT, "256")
    assert cpu_vectors.prefer_wide_vectors(AVX512)
    assert os.environ["XLA_FLAGS"] == "--xla_cpu_prefer_vector_width=256"
    assert cpu_vectors.cpu_has_avx512(AVX512) and not cpu_vectors.cpu_has_avx512(AVX2)


_MOSAIC_DIGEST = """
import hashlib, importlib, numpy as np, jax.numpy as jnp, g2r_jax
unprocess = importlib.import_module("g2r_jax.pipeline")
digests = []
for name in ("s20fe_night",):
    profile = g2r_jax.load_profile(name)
    images = np.random.default_rng(0).integers(0, 256, (3, 96, 130, 3), dtype=np.uint8)
    for batch in (images, (images / 255.0).astype(np.float32)):
        keys = jnp.stack([unprocess.image_key(0, i) for i in range(3)])
        mosaics, _ = unprocess.unprocess_batch(keys, jnp.asarray(batch), profile)
        digests.append(hashlib.sha1(np.asarray(mosaics).tobytes()).hexdigest())
print(" ".join(digests))
"""


def test_vector_width_changes_no_output_byte():
    outputs = []
    for width in ("256", "512"):
        env = dict(os.environ, XLA_FLAGS=f"--xla_cpu_prefer_vector_width={width}", JAX_PLATFORMS="cpu")
        env.pop("G2R_JAX_CPU_VECTOR_WIDTH", None)
        done = subprocess.run([sys.executable, "-c", _MOSAIC_DIGEST], env=env, capture_output=True, text=True,
                              timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        outputs.append(done.stdout.split())
    assert len(outputs[0]) == 2 and outputs[0] == outputs[1]
