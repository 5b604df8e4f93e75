"""Programs kept on disk (`g2r_jax.batch.program_store`): a later process runs the stored program
with the same results, never one stored for other shapes, options or source, and anything
unreadable is traced again."""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax.batch import program_store


def function(x, pair):
    return {"sum": x * pair["a"] + jnp.sin(pair["b"]), "count": jnp.sum(x > 0)}


def arguments(n=5, dtype=np.float32):
    x = np.linspace(-1, 1, n).astype(dtype)
    return x, {"a": np.asarray(2.0, dtype), "b": np.arange(n, dtype=dtype)}


@pytest.fixture
def folder(tmp_path, monkeypatch):
    programs = tmp_path / "programs"     # as beside a compilation cache: stored arrays go to its sibling
    programs.mkdir()
    monkeypatch.setattr(program_store, "store_folder", lambda: programs)
    return programs


def test_a_new_process_runs_the_stored_program_with_the_same_results(folder, monkeypatch):
    expected = jax.jit(function)(*arguments())
    first = program_store.stored_program("f", jax.jit(function))(*arguments())
    assert len(list(folder.glob("*.bin"))) == 1
    from jax import export

    def no_tracing(*_, **__):
        raise AssertionError("traced again although a stored program was there")

    monkeypatch.setattr(export, "export", no_tracing)
    again = program_store.stored_program("f", jax.jit(function))(*arguments())   # as a new process would
    for result in (first, again):
        assert set(result) == {"sum", "count"}
        np.testing.assert_array_equal(result["sum"], expected["sum"])
        assert int(result["count"]) == int(expected["count"])


def test_other_shapes_dtypes_or_names_get_their_own_programs(folder):
    program_store.stored_program("f", jax.jit(function))(*arguments(5))
    program_store.stored_program("f", jax.jit(function))(*arguments(6))
    program_store.stored_program("f", jax.jit(function))(*arguments(5, np.float16))
    program_store.stored_program("g", jax.jit(function))(*arguments(5))
    assert len(list(folder.glob("*.bin"))) == 4


def test_a_damaged_entry_is_traced_again(folder):
    program_store.stored_program("f", jax.jit(function))(*arguments())
    (entry,) = folder.glob("*.bin")
    data = bytearray(entry.read_bytes())
    data[-10] ^= 0xFF
    entry.write_bytes(bytes(data))
    result = program_store.stored_program("f", jax.jit(function))(*arguments())
    np.testing.assert_array_equal(result["sum"], jax.jit(function)(*arguments())["sum"])
    assert entry.read_bytes() != bytes(data)      # rewritten from a fresh trace


def test_the_source_of_the_package_is_part_of_the_key(folder, monkeypatch):
    program_store.stored_program("f", jax.jit(function))(*arguments())
    monkeypatch.setattr(program_store, "_source_digest", lambda: "another version of g2r_jax")
    program_store.stored_program("f", jax.jit(function))(*arguments())
    assert len(list(folder.glob("*.bin"))) == 2


def test_off_without_the_compilation_cache_or_when_asked(monkeypatch):
    cache = jax.config.jax_compilation_cache_dir
    assert program_store.store_folder() == (None if not cache else Path(cache) / "programs")
    monkeypatch.setenv(program_store.DISABLE_VARIABLE, "1")
    assert program_store.store_folder() is None
    result = program_store.stored_program("f", jax.jit(function))(*arguments())
    np.testing.assert_array_equal(result["sum"], jax.jit(function)(*arguments())["sum"])


@pytest.mark.slow
def test_converted_bytes_are_the_same_with_a_stored_program(folder, tmp_path, monkeypatch):
    from PIL import Image

    from g2r_jax.batch import conversion
    from g2r_jax.profile.schema import load_profile

    image = tmp_path / "in" / "frame.png"
    image.parent.mkdir()
    Image.fromarray(np.random.default_rng(3).integers(0, 256, (24, 32, 3), dtype=np.uint8)).save(image)
    profile = load_profile("gopro_hero6")
    outputs = []
    for run, use_store in enumerate((False, True, True)):   # plain; traced and stored; loaded
        monkeypatch.setattr(program_store, "store_folder", (lambda: folder) if use_store else (lambda: None))
        monkeypatch.setattr(conversion, "_COMPILED", {})   # a fresh process
        conversion.convert_files([image], profile, tmp_path / f"out{run}")
        outputs.append((tmp_path / f"out{run}" / "frame.dng").read_bytes())
    assert outputs[0] == outputs[1] == outputs[2]
    assert len(list(folder.glob("*.bin"))) == 1


def test_a_prepared_program_runs_without_tracing_again(folder):
    """`prepare` (shapes only) compiles ahead, on a thread while files decode: the call that follows
    neither traces nor exports, and gives the plain results."""
    traced = []

    def counted(x, pair):
        traced.append(1)
        return function(x, pair)

    program = program_store.stored_program("f", jax.jit(counted))
    x, pair = arguments()
    program.prepare(jax.ShapeDtypeStruct(x.shape, x.dtype), pair)
    assert len(traced) == 1 and len(list(folder.glob("*.bin"))) == 1
    result = program(x, pair)
    assert len(traced) == 1
    np.testing.assert_array_equal(result["sum"], jax.jit(function)(x, pair)["sum"])


def test_a_stored_array_is_made_once_and_read_back_equal(folder):
    made = []

    def make():
        made.append(1)
        return np.random.default_rng(0).random((3, 4, 5)).astype(np.float32)

    first = program_store.stored_array(("scenes", 3), make)
    again = program_store.stored_array(("scenes", 3), make)
    assert len(made) == 1 and again.dtype == np.float32
    np.testing.assert_array_equal(first, again)
    (entry,) = folder.parent.glob("arrays/*.npy")
    data = bytearray(entry.read_bytes())
    data[-3] ^= 0xFF                                 # a damaged entry is made again, never trusted
    entry.write_bytes(bytes(data))
    np.testing.assert_array_equal(program_store.stored_array(("scenes", 3), make), first)
    assert len(made) == 2
    program_store.stored_array(("scenes", 4), make)  # another name, another entry
    assert len(made) == 3
