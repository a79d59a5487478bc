"""The suite's guard against running out of memory mappings (tests/conftest.py, README "Tests")."""

import jax
import jax.numpy as jnp
import pytest

from conftest import MAP_SHARE, map_count, map_limit, release_compiled_programs


def test_map_count_and_limit_read_this_process_and_the_kernel(tmp_path):
    n = map_count()
    if n is None:
        pytest.skip("no /proc on this platform")
    assert n > 0
    cap = map_limit()
    assert cap is None or cap > 0
    maps = tmp_path / "maps"
    maps.write_text("a\nb\nc\n")
    assert map_count(str(maps)) == 3
    assert map_count(str(tmp_path / "missing")) is None
    limit = tmp_path / "limit"
    limit.write_text("65530\n")
    assert map_limit(str(limit)) == 65530
    limit.write_text("not a number")
    assert map_limit(str(limit)) is None


def test_release_clears_the_compiled_programs_only_above_the_share():
    f = jax.jit(lambda x: jnp.sin(x) + 1.0)
    f(jnp.ones(3))
    assert f._cache_size() == 1
    # below the share (or nothing known): nothing is cleared
    assert not release_compiled_programs(count=lambda: 100, limit=lambda: 1000)
    assert not release_compiled_programs(count=lambda: None, limit=lambda: 1000)
    assert not release_compiled_programs(count=lambda: 900, limit=lambda: None)
    assert not release_compiled_programs(count=lambda: int(MAP_SHARE * 1000), limit=lambda: 1000)
    assert f._cache_size() == 1
    # above it: the caches are cleared, and the function compiles again, with the same result
    assert release_compiled_programs(count=lambda: int(MAP_SHARE * 1000) + 1, limit=lambda: 1000)
    assert f._cache_size() == 0
    assert float(f(jnp.ones(3))[0]) == pytest.approx(1.0 + 0.8414709848078965)
    assert f._cache_size() == 1
