"""Compiled programs within the kernel's mapping limit (`g2r_jax.runtime.mapping_limit`): the count
sees a new program's mappings, dropping the programs gives them back, and a function compiled
before still gives the same values after."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax.runtime import mapping_limit


def _programs(count: int, offset: int) -> list:
    """`count` programs compiled for distinct shapes, with their outputs."""
    function = jax.jit(lambda x: jnp.sin(x) * 2.0 + 1.0)
    return [np.asarray(function(jnp.ones(offset + k, jnp.float32))) for k in range(count)]


@pytest.mark.skipif(mapping_limit.mapping_count() is None, reason="no /proc/self/maps on this system")
def test_programs_add_mappings_and_releasing_them_gives_them_back():
    before = mapping_limit.mapping_count()
    first = _programs(20, 1000)
    grown = mapping_limit.mapping_count()
    assert grown > before + 20                      # several mappings per compiled program
    assert mapping_limit.release_if_crowded(share=0.0)
    assert mapping_limit.mapping_count() < grown - 20
    again = _programs(20, 1000)                     # compiled again, same values
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)


def test_nothing_is_released_below_the_share(monkeypatch):
    monkeypatch.setattr(mapping_limit, "mapping_count", lambda: 100)
    monkeypatch.setattr(mapping_limit, "mapping_limit", lambda: 65530)
    cleared = []
    monkeypatch.setattr(jax, "clear_caches", lambda: cleared.append(True))
    assert not mapping_limit.release_if_crowded()
    monkeypatch.setattr(mapping_limit, "mapping_count", lambda: 30000)
    assert mapping_limit.release_if_crowded()
    assert cleared == [True]


def test_nothing_is_done_where_the_system_does_not_tell(monkeypatch):
    monkeypatch.setattr(mapping_limit, "mapping_count", lambda: None)
    assert not mapping_limit.release_if_crowded(share=0.0)
