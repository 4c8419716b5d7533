"""A process fitting record after record must not run out of memory mappings: XLA:CPU keeps each compiled program
mapped, and after ~15 `detect` runs in one process (a benchmark) XLA failed with "LLVM compilation error: Cannot
allocate memory" and the process crashed. Before each fit and each seed nnphd drops JAX's in-memory programs when
the process holds more than MAP_SHARE_MAX of vm.max_map_count (nnphd._config.release_compiled_if_crowded)."""

from __future__ import annotations

import sys

import jax
import jax.numpy as jnp
import pytest

import nnphd._config as config


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's")
def test_the_mappings_of_this_process_and_their_limit_are_read():
    used, limit = config.mapped_regions()
    assert 0 < used < limit


def test_compiled_programs_are_dropped_only_when_the_process_is_crowded(monkeypatch):
    f = jax.jit(lambda x: 2 * x + 1)
    f(jnp.ones(3))
    assert f._cache_size() == 1
    monkeypatch.setattr(config, "mapped_regions", lambda: (30_000, 65_530))  # below half the limit: kept
    assert config.release_compiled_if_crowded() is False and f._cache_size() == 1
    monkeypatch.setattr(config, "mapped_regions", lambda: (40_000, 65_530))  # above: dropped
    assert config.release_compiled_if_crowded() is True and f._cache_size() == 0
    assert float(f(jnp.ones(3))[0]) == 3.0  # and compiled again when next called
    assert config.release_compiled_if_crowded(share=0.7) is False  # a share of one's own
    monkeypatch.setattr(config, "mapped_regions", lambda: None)  # no /proc: nothing to go by, nothing dropped
    assert config.release_compiled_if_crowded() is False


def test_every_fit_checks_first(monkeypatch, tmp_path):
    from nnphd.user import detect
    from tests.fixtures.recordings import make

    calls = []
    monkeypatch.setattr(detect, "release_compiled_if_crowded", lambda: calls.append(1) or True)
    path = make("white-noise", 0).write_csv(tmp_path / "noise.csv")  # refused by the data gate: no training, ~1 s
    rep = detect.detect_file(path, seed=0, steps=4, n_seeds=1, sr_time=0)
    assert rep["status"] == "inconclusive" and calls == [1]
