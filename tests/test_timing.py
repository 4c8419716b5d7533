"""Where a run's time goes (:class:`nnphd.io.timing.StageTimer`): wall seconds per stage, JAX compilation within
each, nothing left registered afterwards. The stages of a whole ``nnphd detect`` run are checked in
tests/test_batch.py (slow)."""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import pytest

from nnphd.io.timing import StageTimer


def test_stages_add_up_and_compilation_is_charged_to_the_stage_that_compiles():
    @jax.jit
    def f(x):
        return jnp.sin(x) * 3.0 + x**2

    x, y = jnp.arange(7.0), jnp.arange(7.0) + 1  # (eager operations compile tiny programs too: made before)
    with StageTimer() as timer:
        with timer.stage("first call"):
            f(x).block_until_ready()
        with timer.stage("second call"):  # the same shape: compiled already
            f(y).block_until_ready()
        with timer.stage("outer"):
            time.sleep(0.02)
            with timer.stage("inner"):  # does not count for the outer stage
                time.sleep(0.05)
        with timer.stage("first call"):  # a stage entered again accumulates
            pass
    before = dict(timer.compile)
    jax.jit(lambda x: jnp.cos(x) - 1.0)(jnp.ones(3)).block_until_ready()  # compiled after the run: not seen
    assert timer.compile == before  # the listener is gone with the run
    timer.add("measured elsewhere", 0.5)
    d = timer.to_dict()
    assert [s["stage"] for s in d["stages"]] == ["first call", "second call", "outer", "inner", "measured elsewhere"]
    by = {s["stage"]: s for s in d["stages"]}
    assert by["first call"]["compile_s"] > 0 and by["second call"]["compile_s"] == 0.0
    assert by["inner"]["s"] >= 0.05 and 0.02 <= by["outer"]["s"] < by["inner"]["s"]
    assert d["compile_s"] == sum(s["compile_s"] for s in d["stages"])
    parts = d["compile_parts_s"]  # (cache retrieval is part of xla: not added again)
    assert d["compile_s"] == pytest.approx(parts["trace"] + parts["lower"] + parts["xla"]) and parts["trace"] > 0
    assert 0 <= parts["cache"] <= parts["xla"]
    assert d["total_s"] + 1e-9 >= sum(s["s"] for s in d["stages"]) and d["other_s"] >= 0.0


def test_time_measured_elsewhere_is_a_stage_of_its_own():
    timer = StageTimer()
    timer.add("reading the file", 1.25)
    with timer:
        pass
    d = timer.to_dict()
    assert d["stages"] == [{"stage": "reading the file", "s": 1.25, "compile_s": 0.0}]
    assert d["total_s"] >= 1.25 and d["other_s"] >= 0.0


def test_compilation_on_worker_processes_is_added_to_the_training_stage():
    from nnphd.user.assembly import with_workers

    tm = {"total_s": 10.0, "compile_s": 1.0, "other_s": 0.0, "note": "wall seconds",
          "stages": [{"stage": "derivatives", "s": 1.0, "compile_s": 0.0},
                     {"stage": "training and trust checks", "s": 8.0, "compile_s": 1.0}]}  # fmt: skip
    seeds = [{"seed": 0, "compile_s": 3.0, "where": "tcp://127.0.0.1:1"}, {"seed": 1, "compile_s": 2.5, "where": "x"}]
    out = with_workers(tm, seeds)
    assert out["compile_s"] == 6.5 and out["stages"][1]["compile_s"] == 6.5 and out["stages"][0]["compile_s"] == 0
    assert out["per_seed"] == seeds and "worker processes" in out["note"]
    assert tm["compile_s"] == 1.0 and tm["stages"][1]["compile_s"] == 1.0 and "worker" not in tm["note"]  # unchanged
    here = [{"seed": 0, "compile_s": 3.0, "where": "in-process"}]  # seen by this process's listener already
    assert with_workers(tm, here)["compile_s"] == 1.0
    threads = [
        {"seed": 0, "compile_s": 0.5, "where": "thread 1 of 2"},
        {"seed": 1, "compile_s": 3.0, "where": "thread 2 of 2"},
    ]
    assert with_workers(tm, threads)["compile_s"] == 1.0  # threads of this process: seen already
