"""The one way nnphd runs independent units of work: a λ-sweep of a study, an experiment of ``reproduce``, a file of
a ``detect`` batch.  Built on Dask distributed.

    from nnphd.parallel import Unit, run_units
    outcomes = run_units([Unit("a", f, {"x": 1}), Unit("b", f, {"x": 2})], workers=2)
    outcomes["a"].value  # or .error

* ``workers=1`` (and no ``scheduler``): every unit runs here, in this process, one after another — the behaviour of
  nnphd before this layer (the calling process keeps its XLA threads and its progress bar).
* ``workers=N``: a ``distributed.LocalCluster`` of N worker *processes* with one thread each, and XLA, OpenBLAS and
  OpenMP held to one thread each (:data:`WORKER_ENV`), so N units fill N cores without fighting over them. Default
  (``None``): one worker per core. Never more workers than units.
* ``scheduler="tcp://host:8786"``: use an existing Dask cluster (``dask scheduler`` + ``dask worker``, or
  dask-jobqueue's ``SLURMCluster``, see docs/scaling.md); the workers must have nnphd installed and see the same ``out``
  folder (a shared filesystem), since the units write their results and caches there.  A malformed address or one
  that does not answer within :data:`CONNECT_TIMEOUT_S` seconds (NNPHD_SCHEDULER_TIMEOUT, a finite number of seconds
  up to a day: :func:`connect_timeout`) raises :class:`SchedulerError` (one line).

**Nothing listens beyond this machine.**  A local cluster's scheduler, workers and their HTTP servers (Dask's
/health, /metrics, …; no dashboard is started) all listen on 127.0.0.1 only; a test lists every listening socket of
the process tree during a run.  Their scratch space is a private folder (:func:`scratch_folder`: mode 0700, removed
when the cluster closes), not Dask's shared and predictable ``<tmp>/dask-scratch-space``.

**Same numbers whatever the number of workers.** A unit's result depends only on its arguments (its seed is one of
them), never on which worker ran it or in what order; the tests compare 1 and 2 workers, and a killed worker.

**Failures are contained.** A unit that raises is reported in its :class:`Outcome` (``ok=False``, ``error`` one
line) and the others finish; a worker that dies (killed, out of memory) is replaced by its nanny and its unit is
rerun elsewhere (``retries`` times, then reported as failed).  Units cache what they finish under their ``out``
folders, so a rerun after a failure resumes.  KeyboardInterrupt is never swallowed: the cluster is shut down and the
interrupt goes on to the caller.

Why Dask and not Ray: Dask distributed is a pure-Python wheel set (~10 MB beside JAX, Ray's is ~70 MB and brings a
C++ runtime with its own object store and dashboard), its LocalCluster starts in seconds on a laptop, a nanny
restarts a killed worker and the scheduler reruns its tasks, and the same code runs on an existing cluster given its
address or on SLURM/PBS through dask-jobqueue.  Nothing in nnphd needs Ray's actors or object store.
"""

from __future__ import annotations

import math
import os
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from typing import Any

from nnphd._config import ONE_THREAD_FLAGS, XLA_FLAG
from nnphd.io.progress import Progress
from nnphd.io.timing import COMPILE_EVENTS  # JAX's duration events of a compilation

__all__ = [
    "CONNECT_TIMEOUT_S",
    "CompileClock",
    "SchedulerError",
    "check_scheduler_address",
    "connect_timeout",
    "local_cluster",
    "UnitsFailed",
    "Unit",
    "Outcome",
    "largest_first",
    "run_units",
    "runs_here",
    "runs_in_this_process",
    "n_workers",
    "default_workers",
    "WORKER_ENV",
]

# each worker process: one XLA thread (no Eigen thread pool), one BLAS/OpenMP thread; the faster XLA:CPU setting of
# nnphd.configure() too (set before the worker imports JAX, so it takes effect)
WORKER_ENV = {
    "XLA_FLAGS": f"{ONE_THREAD_FLAGS} {XLA_FLAG}",
    "JAX_ENABLE_X64": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NNPHD_WORKER": "1",
}


LOOPBACK = "127.0.0.1"  # every socket of a local cluster listens here only

# seconds to wait for an existing scheduler (``scheduler=``) to answer; NNPHD_SCHEDULER_TIMEOUT=seconds overrides it
# (a finite number, 0 < seconds ≤ MAX_CONNECT_TIMEOUT_S: inf or 1e300 overflowed a thread's join deep in a run)
CONNECT_TIMEOUT_S = 30.0
MAX_CONNECT_TIMEOUT_S = 86400.0
TIMEOUT_ENV = "NNPHD_SCHEDULER_TIMEOUT"


class SchedulerError(ValueError):
    """``scheduler`` is not a Dask scheduler address, or none answers there in time: bad input (the command line
    reports it in one line, exit code 2)."""


def check_scheduler_address(address: str) -> str:
    """``address`` if it has the form of a Dask scheduler address over TCP (``tcp://host:port``; a bare
    ``host:port`` is tcp), else :class:`SchedulerError`. Nothing is contacted. Other transports (``tls://`` needs a
    security context, ``ucx://``, ``ws://``) are refused: nnphd passes no configuration for them."""
    from distributed.comm import get_address_host_port, parse_address

    text = str(address).strip()
    bad = SchedulerError(f"--scheduler {address!r} is not a Dask scheduler address (expected tcp://host:port)")
    try:
        scheme, loc = parse_address(text)
        if scheme != "tcp":
            raise SchedulerError(
                f"--scheduler {address!r}: the {scheme}:// transport is not supported (expected tcp://host:port)"
            )
        host, port = get_address_host_port(text)
        if not host or not 0 < int(port) < 65536 or any(c.isspace() or c in "/?#@" for c in loc):
            raise bad
    except (ValueError, TypeError) as e:
        if isinstance(e, SchedulerError):
            raise
        raise bad from None
    return text


def connect_timeout() -> float:
    """Seconds to wait for an existing scheduler: NNPHD_SCHEDULER_TIMEOUT when it is set and not empty, else
    :data:`CONNECT_TIMEOUT_S`. A value that is not a finite number of seconds in (0, :data:`MAX_CONNECT_TIMEOUT_S`]
    (``inf``, ``nan``, ``1e300``, ``-1``, ``0``, ``abc``) is a :class:`SchedulerError` (one line naming the variable;
    exit 2 on the command line), raised before anything is contacted."""
    raw = os.environ.get(TIMEOUT_ENV, "").strip()
    if not raw:
        return CONNECT_TIMEOUT_S
    try:
        t = float(raw)
    except ValueError:
        t = math.nan
    if not (math.isfinite(t) and 0 < t <= MAX_CONNECT_TIMEOUT_S):
        from nnphd.io.escape import one_line

        raise SchedulerError(
            f"{TIMEOUT_ENV}={one_line(repr(raw), 40)} is not a number of seconds: expected a finite number "
            f"above 0 and at most {MAX_CONNECT_TIMEOUT_S:g} (one day); unset, it is {CONNECT_TIMEOUT_S:g}"
        )
    return t


class UnitsFailed(RuntimeError):
    """Units of a job failed (each one's error is in the message); the others finished and are cached, so the same
    call resumes. The command line reports it in one line, exit code 1."""


@dataclass(frozen=True)
class Unit:
    """One independent piece of work: ``fn(**kwargs)`` named ``key`` (unique within a call). ``fn`` must be a
    module-level function (workers import it by name) and its result picklable; it may write files under its own
    ``out`` folder. ``cost``: a guess of its run time in any unit (e.g. a file's size); on Dask workers the
    costliest units start first, so that no long unit starts last while the other workers idle."""

    key: str
    fn: Callable[..., Any]
    kwargs: dict = field(default_factory=dict)
    cost: float = 0.0


@dataclass
class Outcome:
    """What became of a unit: its ``value`` (``ok``) or its one-line ``error``, the seconds it ran and where."""

    key: str
    ok: bool
    value: Any = None
    error: str | None = None
    wall_time_s: float = 0.0
    where: str = "in-process"
    compile_time_s: float = 0.0  # of wall_time_s: JAX tracing, lowering and XLA compilation

    def to_dict(self) -> dict:
        return {
            "key": self.key,
            "ok": self.ok,
            "error": self.error,
            "wall_time_s": self.wall_time_s,
            "compile_time_s": self.compile_time_s,
            "where": self.where,
        }


class CompileClock:
    """Seconds JAX spends compiling while the clock runs (``with CompileClock() as c: ...; c.seconds``), from
    :mod:`jax.monitoring`'s duration events. Process-wide: exact when one unit runs at a time in the process (a
    worker has one thread); ``thread_only``: only the compilations of the thread that started the clock (JAX
    reports a compilation in the thread that asked for it) — a unit on one of several threads."""

    def __init__(self, thread_only: bool = False) -> None:
        self.seconds = 0.0
        self._thread = None
        self._thread_only = thread_only
        self._spans: dict[int, list[tuple[float, float]]] = {}  # per thread: (start, seconds) of what is counted

    def _listen(self, event: str, duration: float, **_kw) -> None:
        me = threading.get_ident()
        if event in COMPILE_EVENTS and (self._thread is None or me == self._thread):
            # JAX reports an event when it ends. One that started after the start of this one, on this thread, ran
            # inside it (tracing a program traces the programs it calls and compiles the operations it runs, each
            # reporting its own duration): counted once, as this one's — summed, a seed's compiling exceeded its
            # wall time (38.5 of 36.8 s)
            d = float(duration)
            start = time.perf_counter() - d
            spans = self._spans.setdefault(me, [])
            inner = [x for x in spans if x[0] >= start]
            if inner:
                self.seconds -= sum(x[1] for x in inner)
                spans[:] = [x for x in spans if x[0] < start]
            spans.append((start, d))
            self.seconds += d

    def __enter__(self) -> CompileClock:
        import jax.monitoring

        self._thread = threading.get_ident() if self._thread_only else None
        jax.monitoring.register_event_duration_secs_listener(self._listen)
        return self

    def __exit__(self, *exc) -> None:
        import jax.monitoring

        jax.monitoring.unregister_event_duration_listener(self._listen)


def as_here(fn: Callable) -> Callable:
    """``fn`` made to run on another thread as it would on this one: under this thread's JAX float64 setting and in
    a copy of its context variables (taken now, copied again per call). ``jax.enable_x64`` is thread-local: a pool
    thread started inside ``with jax.enable_x64(True)`` — as :class:`nnphd.NNPhD` runs — computed in float32, and
    the trajectory-level law fits of ``NNPhD.fit`` failed on a damped pendulum (a float64 carry met a float32 one).
    The context variables carry the stage :class:`nnphd.io.timing.StageTimer` counts compilation in. Every thread
    pool of nnphd runs its work through this."""
    import contextvars

    import jax

    x64 = bool(jax.config.jax_enable_x64)
    ctx = contextvars.copy_context()

    def run(*args, **kwargs):
        with jax.enable_x64(x64):
            return ctx.copy().run(fn, *args, **kwargs)

    return run


def alongside(fn: Callable, /, *args, **kwargs):
    """Start ``fn(*args, cancel=event, **kwargs)`` on a thread of its own, beside the caller's work (:func:`as_here`:
    the caller's float64 setting and context). Returns (future, cancel): ``future.result()`` waits for it and raises
    its error; ``cancel.set()`` asks it to stop where it looks at the event. Nothing waits for the thread here: left
    alone, it ends by itself (a process exits once it has)."""
    from concurrent.futures import ThreadPoolExecutor

    cancel = threading.Event()
    ex = ThreadPoolExecutor(max_workers=1, thread_name_prefix="nnphd-alongside")
    try:
        future = ex.submit(as_here(fn), *args, cancel=cancel, **kwargs)
    finally:
        ex.shutdown(wait=False)
    return future, cancel


def default_workers() -> int:
    """One worker per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover — not Linux
        return max(1, os.cpu_count() or 1)


def n_workers(workers: int | None, scheduler: str | None, n_units: int) -> int:
    """How many local workers :func:`run_units` uses for ``n_units`` units (0: an existing cluster)."""
    if scheduler is not None:
        return 0
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers or workers < 1):
        raise ValueError(f"workers must be an integer ≥ 1, got {workers!r}")
    n = default_workers() if workers is None else int(workers)
    return min(n, max(int(n_units), 1))


def runs_here(workers: int | None, scheduler: str | None, n_units: int) -> bool:
    """Whether :func:`run_units` runs ``n_units`` units in this process (so a unit may report fine progress)."""
    return n_workers(workers, scheduler, n_units) == 1


def _one_line(e: BaseException) -> str:
    text = " ".join(f"{type(e).__name__}: {e}".split())
    return text[:500] + ("…" if len(text) > 500 else "")


def _call(fn: Callable[..., Any], kwargs: dict) -> tuple[Any, float, float, str]:
    """Run one unit in a worker: nnphd's process-wide settings (float64; the XLA flags came with the worker's
    environment), then ``fn(**kwargs)``; returns (value, seconds, seconds of compilation, worker pid)."""
    from nnphd._config import configure

    configure()
    t0 = time.perf_counter()
    with CompileClock() as clock:
        value = fn(**kwargs)
    return value, time.perf_counter() - t0, clock.seconds, f"worker pid {os.getpid()}"


def run_units(
    units: Sequence[Unit],
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Progress | None = None,
    retries: int = 2,
    on_outcome: Callable[[Outcome], None] | None = None,
    threads: bool = False,
    cancel: threading.Event | None = None,
) -> dict[str, Outcome]:
    """Run every unit; return {key: :class:`Outcome`} in the units' order.

    ``workers``: 1 runs in this process; N > 1 starts a local Dask cluster of N single-threaded worker processes
    (never more than there are units); ``None`` is one per core. ``scheduler``: the address of an existing Dask
    scheduler (``workers`` is then ignored). ``retries``: how often a unit whose worker died is started again.
    ``progress(done, total, message)`` follows finished units; ``on_outcome`` is called with each as it finishes
    (in the order they finish).

    ``threads``: the local units run on ``workers`` threads of this process instead (no scheduler; the same
    numbers) — for units that run the same JAX programs, which then are traced and compiled once for all of them,
    and whose time is spent in compiled XLA code, which runs outside Python's global lock (a ``detect``'s seeds:
    7.9–10.0 s on 2 threads against 12.0–12.5 s on 2 worker processes and 13.5 s one after another, identical
    reports). Failures are contained as on workers; a unit's ``compile_time_s`` counts its own thread's. A thread
    cannot be stopped from outside: on an interrupt ``cancel`` (an Event the units watch) is set, and the units not
    started are not started.
    """
    units = list(units)
    keys = [u.key for u in units]
    if len(set(keys)) != len(keys):
        raise ValueError(f"unit keys must be unique, got {keys}")
    n = n_workers(workers, scheduler, len(units))
    if scheduler is not None:
        scheduler = check_scheduler_address(scheduler)
        connect_timeout()  # a bad NNPHD_SCHEDULER_TIMEOUT is refused before any unit is submitted
    if not units:
        return {}
    if n == 1:
        return _run_here(units, progress, on_outcome)
    if threads and scheduler is None:
        return _run_threads(units, n, progress, on_outcome, cancel)
    return _run_dask(units, n, scheduler, progress, retries, on_outcome)


def largest_first(units: Sequence[Unit]) -> list[Unit]:
    """The order units are handed to Dask workers: by decreasing :attr:`Unit.cost`, ties in the given order."""
    return sorted(units, key=lambda u: -u.cost)


def list_schedule(durations: Sequence[float], workers: int, overhead_s: float = 0.0) -> dict:
    """The makespan of independent units on ``workers`` identical workers, as :func:`run_units` hands them out:
    largest first, each to the worker that frees first (a list schedule; Graham's bound: makespan ≤ total/W + the
    longest unit). ``overhead_s``: a worker's cost per unit (dispatch, transfer, result). Returns {"makespan_s",
    "total_s" (the work, overhead included), "efficiency" (total / (workers × makespan)), "loads_s" (per worker)}
    — how a cluster's time is simulated from unit times measured on one machine."""
    import heapq

    if int(workers) != workers or workers < 1:
        raise ValueError(f"workers must be an integer ≥ 1, got {workers!r}")
    if any(not (d >= 0) for d in durations) or not overhead_s >= 0:
        raise ValueError("unit durations and the overhead must be non-negative numbers")
    loads = [(0.0, i) for i in range(int(workers))]
    for d in sorted(durations, reverse=True):
        t, i = heapq.heappop(loads)
        heapq.heappush(loads, (t + float(d) + overhead_s, i))
    per = [t for t, _ in sorted(loads, key=lambda x: x[1])]
    makespan = max(per)
    total = sum(per)
    return {
        "makespan_s": makespan,
        "total_s": total,
        "efficiency": total / (workers * makespan) if makespan > 0 else 1.0,
        "loads_s": per,
    }


def _run_one(u: Unit, thread_only: bool = False, where: str = "in-process", n_threads: int = 0) -> Outcome:
    """``u`` run in this process (its error contained in the outcome); with ``n_threads``, on a thread of
    :func:`_run_threads`' pool, named in ``where`` ("thread k of n")."""
    if n_threads:
        where = f"thread {int(threading.current_thread().name.rsplit('_', 1)[-1]) + 1} of {n_threads}"
    t0 = time.perf_counter()
    clock = CompileClock(thread_only)
    try:
        with clock:
            value = u.fn(**u.kwargs)
        return Outcome(
            u.key, True, value, wall_time_s=time.perf_counter() - t0, where=where, compile_time_s=clock.seconds
        )
    except (KeyboardInterrupt, SystemExit, MemoryError):
        raise
    except Exception as e:  # contained: reported in the outcome, the other units go on
        if os.environ.get("NNPHD_TRACEBACK"):
            traceback.print_exc()
        return Outcome(u.key, False, error=_one_line(e), wall_time_s=time.perf_counter() - t0, where=where)


def runs_in_this_process(where: str) -> bool:
    """Whether an :class:`Outcome`'s ``where`` is this process (in-process, or one of its threads)."""
    return where == "in-process" or where.startswith("thread ")


def _run_threads(units, n, progress, on_outcome, cancel=None) -> dict[str, Outcome]:
    """The units on ``n`` threads of this process (:func:`run_units`' ``threads``), handed out in order; an
    interrupt (or any error here) sets ``cancel``, cancels the units not started and goes on to the caller once the
    running ones have returned."""
    from concurrent.futures import ThreadPoolExecutor, as_completed

    out: dict[str, Outcome] = {}
    with ThreadPoolExecutor(max_workers=n, thread_name_prefix="nnphd-unit") as ex:
        try:
            run = as_here(_run_one)
            futures = {ex.submit(run, u, True, n_threads=n): u.key for u in units}
            if progress:
                progress(0, len(units), f"{len(units)} units on {n} threads")
            for fut in as_completed(futures):
                oc = fut.result()
                out[oc.key] = oc
                if on_outcome:
                    on_outcome(oc)
                if progress:
                    progress(len(out), len(units), f"{oc.key}: {'done' if oc.ok else 'failed'}")
        except BaseException:
            if cancel is not None:
                cancel.set()
            ex.shutdown(cancel_futures=True)
            raise
    return {u.key: out[u.key] for u in units}


def _run_here(units, progress, on_outcome) -> dict[str, Outcome]:
    out: dict[str, Outcome] = {}
    for i, u in enumerate(units):
        if progress:
            progress(i, len(units), f"{u.key}: running")
        # its own thread's compilations only: a detect run's library base compiles beside the seed on another thread
        # of this process (counted process-wide, a seed's compiling exceeded its wall time: 38.5 of 36.8 s)
        oc = _run_one(u, thread_only=True)
        out[u.key] = oc
        if on_outcome:
            on_outcome(oc)
        if progress:
            progress(i + 1, len(units), f"{u.key}: {'done' if oc.ok else 'failed'}")
    return out


@contextmanager
def scratch_folder():
    """A private scratch folder for a local cluster (yields its path): made by :func:`tempfile.mkdtemp` — an
    unpredictable name, mode 0700, owned by this user — instead of Dask's default ``<tmp>/dask-scratch-space``,
    which is shared by every user of the machine and predictable (Dask also puts its scratch folder first on
    ``sys.path``: one made by someone else could plant modules). On leaving, the folder and everything in it are
    removed, and the ``sys.path`` entries Dask left pointing into it are dropped (a later folder of the same name
    is never imported from)."""
    import shutil
    import sys
    import tempfile

    folder = tempfile.mkdtemp(prefix="nnphd-dask-")
    try:
        yield folder
    finally:
        inside = os.path.join(folder, "")
        sys.path[:] = [p for p in sys.path if not (p == folder or str(p).startswith(inside))]
        shutil.rmtree(folder, ignore_errors=True)


@contextmanager
def local_cluster(n: int):
    """A ``distributed.LocalCluster`` of ``n`` single-threaded worker processes (nannied, :data:`WORKER_ENV`) whose
    every socket listens on 127.0.0.1 only: the scheduler and the workers, and their HTTP servers (health and
    metrics routes; no dashboard is started, so bokeh is never needed). The scheduler, nannies and workers keep
    their scratch files in a private folder (:func:`scratch_folder`: mode 0700, removed afterwards), never in the
    system's shared temporary folder. Closed on leaving, also on an error."""
    import dask
    from distributed import LocalCluster

    with scratch_folder() as scratch, dask.config.set({"temporary-directory": scratch}):  # the scheduler's too
        with LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host=LOOPBACK,
            scheduler_port=0,
            # the scheduler's HTTP server (Dask starts one even without a dashboard): loopback, a free port; the
            # default ":8787"/":0" means every interface. The workers' HTTP servers follow their host (127.0.0.1).
            dashboard_address=f"{LOOPBACK}:0",
            worker_dashboard_address=None,
            env=dict(WORKER_ENV),
            silence_logs=50,  # logging.CRITICAL: Dask's own log lines stay off the user's terminal
            local_directory=scratch,  # the nannies' and workers' scratch space (Dask adds dask-scratch-space/)
        ) as cluster:
            yield cluster


def _client(scheduler: str):
    """A Client of the existing scheduler at ``scheduler``; :class:`SchedulerError` (one line) if none answers in
    time or what answers is no Dask scheduler. The connection is made on a daemon thread given 2·``timeout`` + 1 s in
    all: Dask's own timeout does not cover a server that accepts and then says nothing Dask understands (an HTTP
    server hung it for minutes), and a reply read as a frame length asks for exabytes (a MemoryError)."""
    import threading

    from distributed import Client

    timeout = connect_timeout()
    box: dict = {}

    def connect() -> None:
        try:
            box["client"] = Client(scheduler, timeout=timeout)
        except BaseException as e:  # noqa: BLE001 — handed to the caller below
            box["error"] = e

    th = threading.Thread(target=connect, name="nnphd-scheduler-connect", daemon=True)
    th.start()
    th.join(2.0 * timeout + 1.0)
    if th.is_alive():
        raise SchedulerError(
            f"--scheduler {scheduler!r}: no Dask scheduler answered within {timeout:g} s (something may listen "
            "there that is not a Dask scheduler; expected the address printed by `dask scheduler`)"
        )
    e = box.get("error")
    if e is None:
        return box["client"]
    why = " ".join(str(e).split())[:200]
    if isinstance(e, (OSError, TimeoutError)):  # refused, unknown host, or no answer in time
        why = "" if why.startswith("Timed out") else f" ({type(e).__name__}: {why})"
        raise SchedulerError(
            f"--scheduler {scheduler!r} cannot be reached within {timeout:g} s: no Dask scheduler answers there{why}"
        ) from None
    if isinstance(e, KeyboardInterrupt):
        raise e
    raise SchedulerError(
        f"--scheduler {scheduler!r}: what answers there is not a Dask scheduler ({type(e).__name__}: {why[:100]}); "
        "expected the address printed by `dask scheduler`"
    ) from None


def _run_dask(units, n, scheduler, progress, retries, on_outcome) -> dict[str, Outcome]:
    import dask
    from distributed import Client, as_completed

    # a worker lost while it ran a unit: the scheduler reruns the unit elsewhere, up to `retries` more times
    config = {
        "distributed.scheduler.allowed-failures": int(retries),
        # Dask's nannies set MALLOC_TRIM_THRESHOLD_=65536 in their workers (to hand memory back sooner); JAX frees
        # and allocates buffers all the time, and with it a λ-sweep ran 2× slower in a worker (23 s vs 11 s here)
        "distributed.nanny.pre-spawn-environ": {k: v for k, v in WORKER_ENV.items() if k.endswith("_NUM_THREADS")},
        # the workers' statistical profiler samples every thread's stack every 10 ms; on JAX's many short dispatches
        # it cost 15–30 % (two λ-sweeps on 2 workers: 21.8/22.1 s with it, 18.8/18.7 s without, one run each)
        "distributed.worker.profile.enabled": False,
    }
    with dask.config.set(config), ExitStack() as stack:
        if scheduler is None:
            client = Client(stack.enter_context(local_cluster(n)))
        else:
            client = _client(scheduler)
        try:
            futures = {}
            for u in largest_first(units):
                fut = client.submit(_call, u.fn, u.kwargs, key=f"nnphd-{u.key}-{time.time_ns()}", pure=False)
                futures[fut] = u.key
            out: dict[str, Outcome] = {}
            if progress:
                progress(0, len(units), f"{len(units)} units on {n if scheduler is None else 'the'} Dask workers")
            for fut in as_completed(list(futures)):
                key = futures[fut]
                try:
                    value, wall, compile_s, where = fut.result()
                    oc = Outcome(key, True, value, wall_time_s=wall, where=where, compile_time_s=compile_s)
                except (KeyboardInterrupt, SystemExit):
                    raise
                except Exception as e:  # the unit raised, or its worker died more than `retries` times
                    oc = Outcome(key, False, error=_one_line(e), where="dask")
                out[key] = oc
                if on_outcome:
                    on_outcome(oc)
                if progress:
                    progress(len(out), len(units), f"{key}: {'done' if oc.ok else 'failed'}")
            return {u.key: out[u.key] for u in units}
        finally:
            client.close()
