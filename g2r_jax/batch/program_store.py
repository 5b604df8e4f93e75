"""Traced programs kept on disk, so that a new process does not trace and lower them again.

JAX's persistent compilation cache (`g2r_jax.runtime.compile_cache`) skips XLA's compilation, but
every process still traces the conversion in Python and lowers it to StableHLO before it can look
the cache up: most of a warm `g2r-convert`'s first frame (docs/pages/validation/startup.md).
`stored_program(function)` serialises what `jax.export` made of `function` for given argument
shapes, next to the compilation cache, and later processes call the deserialised program: the same
StableHLO, so the same compiled code and the same bytes.

A stored program is used only when everything that shaped it is the same: the caller's key (the
option set), the arguments' pytree structure, shapes and dtypes, JAX's version and configuration,
the backend, and the source of g2r_jax itself (a SHA-256 of its `.py` files). Anything else, or a
file that does not read back, means tracing as usual: never an old program. Off when the
compilation cache is off, and when `jax.export` cannot serialise (it needs `flatbuffers`).
"""

from __future__ import annotations

import hashlib
import os
from functools import lru_cache
from pathlib import Path

import jax

_FORMAT = b"g2r-program-1\n"
DISABLE_VARIABLE = "G2R_JAX_NO_PROGRAM_STORE"


@lru_cache(maxsize=1)
def _source_digest() -> str:
    """SHA-256 of every `.py` file of the package (names and contents), in a fixed order."""
    package = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def store_folder() -> Path | None:
    """Where programs are kept: `programs/` beside the compilation cache; None when that cache is
    off, or `G2R_JAX_NO_PROGRAM_STORE=1` (to compare, benchmarks/cli_startup.py)."""
    if os.environ.get(DISABLE_VARIABLE, "").strip().lower() not in ("", "0", "false", "no"):
        return None
    cache = jax.config.jax_compilation_cache_dir
    return Path(cache) / "programs" if cache else None


def stored_array(name: str, make):
    """`make()`, a numpy array that is a pure function of `name` and the package's source, read
    from the store when an earlier process kept it (checksummed, as a program), else made and
    kept; just `make()` when the store is off. For inputs that cost more to make than to read
    (the audit's scene sets: about 2 s of painting per 24 scenes of 424 x 564)."""
    import io

    import numpy as np

    folder = store_folder()
    if folder is None:
        return make()
    path = folder.parent / "arrays" / (hashlib.sha256(repr((name, _source_digest())).encode()).hexdigest() + ".npy")
    data = _checked_payload(path)
    if data is not None:
        try:
            return np.load(io.BytesIO(data), allow_pickle=False)
        except Exception:  # noqa: BLE001 - an unreadable entry is made again
            pass
    array = np.asarray(make())
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=False)
    _store(path, buffer.getvalue())
    return array


def _key(name: str, leaves, treedef) -> str:
    shapes = [(tuple(leaf.shape), str(leaf.dtype)) for leaf in leaves]
    config = sorted((k, repr(v)) for k, v in jax.config.values.items() if k != "jax_compilation_cache_dir")
    text = repr((name, str(treedef), shapes, jax.__version__, jax.default_backend(), config, _source_digest()))
    return hashlib.sha256(text.encode()).hexdigest()


def _checked_payload(path: Path) -> bytes | None:
    """The payload of a stored entry whose header and SHA-256 check; None otherwise."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    head, check, payload = data[:len(_FORMAT)], data[len(_FORMAT):len(_FORMAT) + 32], data[len(_FORMAT) + 32:]
    if head != _FORMAT or hashlib.sha256(payload).digest() != check:
        return None
    return payload


def _load(path: Path):
    from jax import export

    payload = _checked_payload(path)
    if payload is None:
        return None
    try:
        return export.deserialize(bytearray(payload))
    except Exception:  # noqa: BLE001 - an unreadable entry is traced again, never trusted
        return None


def _store(path: Path, payload: bytes) -> None:
    from g2r_jax.io.atomic import atomic_write_bytes

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(path, _FORMAT + hashlib.sha256(payload).digest() + payload)
    except Exception:  # noqa: BLE001 - a store that cannot be written only costs the next start-up
        pass


def _save(path: Path, exported) -> None:
    _store(path, bytes(exported.serialize()))


def stored_program(name: str, jitted):
    """`jitted` (a `jax.jit` function of pytrees of arrays) as a function that, per argument shape,
    runs the program stored on disk by an earlier process, or traces, stores and runs it.

    **Arguments:** `name`: what distinguishes this function from others of the same arguments
    (e.g. its option set); `jitted`: the function.

    **Returns:** a function with `jitted`'s signature and results, and a `prepare` attribute
    that compiles it ahead for given argument shapes.
    """
    programs = {}

    def program_for(args):
        """(the stored program or None, the flat leaves); None, None when the store is off."""
        folder = store_folder()
        if folder is None:
            return None, None
        leaves, treedef = jax.tree_util.tree_flatten(args)
        leaves = [leaf if isinstance(leaf, (jax.ShapeDtypeStruct, jax.Array)) else jax.device_put(leaf) for leaf in leaves]
        key = _key(name, leaves, treedef)
        if key not in programs:
            programs[key] = _program(folder / f"{key}.bin", jitted, leaves, treedef)
        return programs[key], leaves

    def call(*args):
        program, leaves = program_for(args)
        return program(*leaves) if program is not None else jitted(*args)

    def prepare(*args):
        """Load (or trace and store) and compile the program for arguments like these (arrays or
        `jax.ShapeDtypeStruct`s) without running it, so that a later call only computes: to be
        done on a thread while the inputs are being decoded."""
        program, leaves = program_for(args)
        if program is not None:
            program.lower(*leaves).compile()
        else:
            jitted.lower(*args).compile()

    call.prepare = prepare
    return call


def _program(path: Path, jitted, leaves, treedef):
    """The stored program of these arguments (exported and stored first when missing), called on
    the flat leaves; None when `jax.export` cannot serialise here."""
    from jax import export

    exported = _load(path)
    if exported is None:
        try:
            flat = jax.jit(lambda *flat_leaves: jitted(*jax.tree_util.tree_unflatten(treedef, flat_leaves)))
            exported = export.export(flat)(*[jax.ShapeDtypeStruct(leaf.shape, leaf.dtype) for leaf in leaves])
            exported.serialize()   # raises when flatbuffers is missing: then plain tracing, every run
        except Exception:  # noqa: BLE001 - the store is an optimisation only
            return None
        _save(path, exported)
    return jax.jit(exported.call)

