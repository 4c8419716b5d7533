"""The execution layer (nnphd.parallel, Dask distributed): failures contained, the same numbers with 1 and 2 workers,
a real local cluster that loses a worker mid-run and still delivers every result."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from nnphd.paper.sweep import SweepSettings, run_sweep
from nnphd.parallel import (
    CompileClock,
    Outcome,
    Unit,
    local_cluster,
    n_workers,
    run_units,
    runs_here,
    runs_in_this_process,
)

GRID = [("ho+ld", 0), ("ho+mf", 0), ("ho+ld", 1), ("ho+pf", 2)]
SMALL = dict(p=1, steps=60, lambdas=(0.5, 2.0), n_train=64, n_test=64)


def _units():
    return [
        Unit(f"{s}/{seed}", run_sweep, dict(system=s, settings=SweepSettings(seed=seed, **SMALL))) for s, seed in GRID
    ]


def _numbers(outs: dict[str, Outcome]) -> dict[str, list[float]]:
    return {k: [(r.L_e, r.L_b) for r in o.value.table] for k, o in outs.items()}


@pytest.fixture(scope="module")
def in_process():
    outs = run_units(_units(), workers=1)
    assert all(o.ok and o.where == "in-process" for o in outs.values())
    return _numbers(outs)


def _boom(x):
    if x == 2:
        raise ValueError("unit two\nis broken")
    return x * 10


def test_in_process_failures_are_contained():
    seen = []
    outs = run_units([Unit(f"u{i}", _boom, {"x": i}) for i in range(4)], workers=1, on_outcome=seen.append)
    assert list(outs) == ["u0", "u1", "u2", "u3"]  # the units' order
    assert [outs[k].value for k in ("u0", "u1", "u3")] == [0, 10, 30]
    bad = outs["u2"]
    assert not bad.ok and bad.value is None
    assert bad.error == "ValueError: unit two is broken"  # one line
    assert [o.key for o in seen] == ["u0", "u1", "u2", "u3"]


def _jitted(x):
    import jax
    import jax.numpy as jnp

    return float(jax.jit(lambda a: jnp.sum(jnp.sin(a) * a**2) + x)(jnp.arange(5.0)))


def test_threads_same_numbers_and_failures_contained():
    """``threads=True``: the units on threads of this process give the numbers of the run one after another, in the
    units' order, with a failing unit's one-line error and each thread named in ``where``."""
    units = [*(Unit(f"j{i}", _jitted, {"x": i}) for i in range(3)), Unit("boom", _boom, {"x": 2})]
    here = run_units(units, workers=1)
    seen = []
    outs = run_units(units, workers=2, threads=True, on_outcome=seen.append)
    assert list(outs) == ["j0", "j1", "j2", "boom"] and sorted(o.key for o in seen) == sorted(outs)
    assert [outs[k].value for k in ("j0", "j1", "j2")] == [here[k].value for k in ("j0", "j1", "j2")]
    assert outs["j1"].value == pytest.approx(here["j0"].value + 1, rel=1e-12)
    assert not outs["boom"].ok and outs["boom"].error == "ValueError: unit two is broken"
    assert {o.where for o in outs.values()} <= {"thread 1 of 2", "thread 2 of 2"}
    assert all(runs_in_this_process(o.where) for o in outs.values()) and not runs_in_this_process("worker pid 7")


def _until(flag, seen, started):
    seen.append("started")
    started.set()
    if flag.wait(60):  # a unit that watches the cancel event, as assess's seeds do after each round
        seen.append("cancelled")
    return 0


def _after(started):
    return started.wait(60)


def test_threads_an_interrupt_sets_cancel_and_goes_on():
    """An interrupt while units run on threads (here raised by ``on_outcome`` as the first unit finishes): the event
    the running units watch is set, and the interrupt reaches the caller once they have returned."""
    flag, started, seen = threading.Event(), threading.Event(), []

    def interrupt(_oc):
        raise KeyboardInterrupt

    watch = {"flag": flag, "seen": seen, "started": started}
    units = [Unit("watching", _until, watch), Unit("quick", _after, {"started": started})]
    with pytest.raises(KeyboardInterrupt):
        run_units(units, workers=2, threads=True, on_outcome=interrupt, cancel=flag)
    assert flag.is_set() and seen == ["started", "cancelled"]


def test_a_thread_only_compile_clock_sees_its_own_thread():
    """A compilation in another thread counts on a process-wide clock, not on a thread-only one."""
    import jax
    import jax.numpy as jnp

    def compile_elsewhere():
        jax.jit(lambda a: jnp.cos(a) * 3.25 + a**3)(jnp.arange(7.0)).block_until_ready()

    with CompileClock() as everywhere, CompileClock(thread_only=True) as mine:
        th = threading.Thread(target=compile_elsewhere)
        th.start()
        th.join()
    assert everywhere.seconds > 0 and mine.seconds == 0
    with CompileClock(thread_only=True) as mine:
        compile_elsewhere()
    assert mine.seconds > 0


def test_a_compilation_inside_another_counts_once():
    """JAX reports an event when it ends; one that ran inside another (an inner program traced while the outer one
    is) is counted once, as the outer one's: the clock never exceeds the wall time. Events recorded here with
    jax.monitoring, their spans made with sleeps: 0.1 s with 0.05 s inside it, then 0.02 s."""
    import jax.monitoring

    from nnphd.io.timing import COMPILE_PARTS

    trace, lower = list(COMPILE_PARTS)[:2]
    with CompileClock(thread_only=True) as clock:
        t0 = time.perf_counter()
        time.sleep(0.05)
        jax.monitoring.record_event_duration_secs(lower, 0.05)  # the inner one ends first
        time.sleep(0.05)
        jax.monitoring.record_event_duration_secs(trace, time.perf_counter() - t0)  # the outer one, around it
        time.sleep(0.02)
        jax.monitoring.record_event_duration_secs(lower, 0.02)  # after it: counted
        wall = time.perf_counter() - t0
    assert clock.seconds == pytest.approx(0.12, abs=0.015) and clock.seconds <= wall


def test_argument_checks():
    with pytest.raises(ValueError, match="unique"):
        run_units([Unit("a", _boom, {"x": 0}), Unit("a", _boom, {"x": 1})], workers=1)
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="workers must be an integer"):
            run_units([Unit("a", _boom, {"x": 0})], workers=bad)
    assert run_units([], workers=3) == {}
    # never more workers than units; an existing cluster is "0 local workers"
    assert n_workers(8, None, 3) == 3 and n_workers(2, None, 10) == 2 and n_workers(4, "tcp://x:1", 9) == 0
    assert runs_here(5, None, 1) and not runs_here(2, None, 2) and not runs_here(1, "tcp://x:1", 3)


@pytest.mark.slow  # an end-to-end run of tens of seconds: slow tier (`python3 dev.py test --slow`, and CI)
def test_two_workers_same_numbers_and_a_failing_unit(in_process):
    """A local cluster of 2 single-threaded worker processes gives every unit bit for bit the numbers of the run in
    this process (nnphd.configure() holds XLA to one thread here too); a unit that raises there is reported with its
    one-line error and the others finish."""
    import sys

    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import this test module
    try:
        outs = run_units([*_units(), Unit("boom", _boom, {"x": 2})], workers=2)
    finally:
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    bad = outs.pop("boom")
    assert not bad.ok and bad.error == "ValueError: unit two is broken"
    assert all(o.ok for o in outs.values()), {k: o.error for k, o in outs.items()}
    assert len({o.where for o in outs.values()}) == 2 and "in-process" not in {o.where for o in outs.values()}
    assert _numbers(outs) == in_process
    assert all(0 <= o.compile_time_s < o.wall_time_s for o in outs.values())  # measured in the workers
    assert sum(o.compile_time_s for o in outs.values()) > 0.5


@pytest.mark.slow  # an end-to-end run of tens of seconds: slow tier (`python3 dev.py test --slow`, and CI)
def test_killed_worker_every_result_still_comes(in_process):
    """A worker process SIGKILLed while the grid runs: its nanny starts a new one, the scheduler reruns the lost
    unit, and every result arrives identical to the 1-worker run."""
    from distributed import Client

    with local_cluster(2) as cluster:  # the cluster run_units starts (loopback only), here to kill one of its workers
        with Client(cluster) as client:
            pids = list(client.run(os.getpid).values())
        assert len(pids) == 2
        killed = []

        def kill_one(_outcome):
            if not killed:  # after the first unit finished, both workers are busy with the next ones
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])

        # the first unit's compile takes seconds: kill a worker while it is surely mid-unit, too
        timer = threading.Timer(2.0, lambda: kill_one(None))
        timer.start()
        try:
            outs = run_units(_units(), scheduler=cluster.scheduler_address, on_outcome=kill_one)
        finally:
            timer.cancel()
        with Client(cluster) as client:
            after = set(client.run(os.getpid).values())
    assert killed and killed[0] not in after  # the worker was really killed (and replaced)
    assert all(o.ok for o in outs.values()), {k: o.error for k, o in outs.items()}
    assert _numbers(outs) == in_process


def test_cli_failed_units_are_one_line_exit_1(tmp_path, capsys, monkeypatch):
    """A unit that fails inside a command: one line naming it (not "internal error"), exit code 1."""
    import nnphd.paper.lambda_p as lp
    from nnphd.cli import main

    def broken(**kw):
        raise ValueError("no data")

    monkeypatch.setattr(lp, "lambda_p_subrun", broken)
    argv = ["study", "lambda-p", "--systems", "ho+ld", "--ps", "1", "--lambdas", "0.5,2", "--steps", "4"]
    rc = main([*argv, "--workers", "1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert rc == 1 and len(err.splitlines()) == 1, err
    assert "1 of 1 sweeps failed (ho+ld/p=1: ValueError: no data)" in err and "internal error" not in err
