"""Shared test fixtures: the path to ../shared/data (tests needing it skip cleanly without it)."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO_ROOT / ".." / "shared" / "data"


@pytest.fixture
def shared_data() -> Path:
    if not SHARED_DATA.exists():
        pytest.skip("../shared/data is not present (measured data for development only)")
    return SHARED_DATA


@pytest.fixture(autouse=True)
def _own_downstream_cache(tmp_path, monkeypatch):
    """Each test gets an empty store of finished downstream trainings (`downstream.base.cache`): no test
    reuses another's (or a user's) results."""
    monkeypatch.setenv("G2R_JAX_DOWNSTREAM_CACHE", str(tmp_path / "downstream-cache"))


@pytest.fixture(autouse=True)
def _no_persistent_compilation_cache_in_process(monkeypatch):
    """Commands run in this process (their `main`) do not turn on JAX's persistent compilation
    cache for it: writing and reading its serialised executables crashed test workers with
    segmentation faults (jax compilation_cache put/get, 2026-12-07, two of two clean-clone runs),
    which took a worker and its test down. Commands run as subprocesses still use the cache."""
    from g2r_jax.runtime import compile_cache

    monkeypatch.setattr(compile_cache, "enable", lambda *args, **kwargs: None)
