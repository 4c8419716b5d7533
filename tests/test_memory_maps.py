"""A process fitting record after record must not run out of memory mappings: XLA:CPU keeps each compiled program
mapped, and after ~15 `detect` runs in one process (a benchmark) XLA failed with "LLVM compilation error: Cannot
allocate memory" and the process crashed. Before each fit and each seed nnphd drops JAX's in-memory programs when
the process holds more than MAP_SHARE_MAX of vm.max_map_count (nnphd.release_compiled_if_crowded)."""

from __future__ import annotations

import sys

import jax
import jax.numpy as jnp
import pytest

import nnphd


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's")
def test_the_mappings_of_this_process_and_their_limit_are_read():
    used, limit = nnphd.mapped_regions()
    assert 0 < used < limit


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's")
def test_compiled_programs_are_dropped_only_when_the_process_is_crowded(monkeypatch):
    f = jax.jit(lambda x: 2 * x + 1)
    f(jnp.ones(3))
    assert f._cache_size() == 1
    used, limit = nnphd.mapped_regions()
    # a share above what the process holds (1000 mappings of room): kept; half of what it holds: dropped
    assert nnphd.release_compiled_if_crowded(share=(used + 1000) / limit) is False and f._cache_size() == 1
    assert nnphd.release_compiled_if_crowded(share=used / 2 / limit) is True and f._cache_size() == 0
    assert float(f(jnp.ones(3))[0]) == 3.0  # and compiled again when next called
    assert f._cache_size() == 1
    assert used + 1000 < limit / 2  # the default share is half the limit: this process is far below it
    assert nnphd.release_compiled_if_crowded() is False and f._cache_size() == 1
    real_open = open

    def no_proc(path, *a, **k):
        if str(path).startswith("/proc/"):
            raise FileNotFoundError(2, "No such file or directory", str(path))
        return real_open(path, *a, **k)

    monkeypatch.setattr("builtins.open", no_proc)  # no /proc: nothing to go by, nothing dropped
    assert nnphd.mapped_regions() is None
    assert nnphd.release_compiled_if_crowded(share=0.0) is False and f._cache_size() == 1


def test_every_fit_checks_first(monkeypatch, tmp_path):
    from nnphd.user import detect
    from tests.fixtures.recordings import make

    calls = []
    monkeypatch.setattr(detect, "release_compiled_if_crowded", lambda: calls.append(1) or True)
    path = make("white-noise", 0).write_csv(tmp_path / "noise.csv")  # refused by the data gate: no training, ~1 s
    rep = detect.detect_file(path, seed=0, steps=4, n_seeds=1, sr_time=0)
    assert rep["status"] == "inconclusive" and calls == [1]
