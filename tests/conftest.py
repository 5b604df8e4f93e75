"""Shared test fixtures: the path to ../shared/data (tests needing it skip cleanly without it)."""

from __future__ import annotations

from pathlib import Path

import pytest

from g2r_jax.runtime.mapping_limit import release_if_crowded

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
def _compiled_programs_within_the_mapping_limit():
    """A test worker compiles programs for hundreds of shapes; past the kernel's limit on its memory
    mappings XLA's JIT aborted it (`g2r_jax.runtime.mapping_limit`), so each test ends by dropping
    the compiled programs when they crowd it."""
    yield
    release_if_crowded()
