"""Where the time of one run goes: wall seconds per named stage, and within each the seconds JAX spent compiling.

``with StageTimer() as timer:`` registers a :mod:`jax.monitoring` listener for the run only (removed on exit: no
global state outlives it); ``with timer.stage("the law table"):`` adds the wall time of the block to that stage
(a stage entered again accumulates) and every compilation event inside it to the stage's compile seconds —
tracing, lowering to MLIR and the XLA compilation, or the retrieval from the persistent compilation cache when it
hits. Stages do not nest: a stage entered inside another is counted for the inner one only, and the outer one's
wall time excludes it. Compilations in other processes (Dask workers) are not seen; ``to_dict`` says so.

Work on another thread beside the run's own (``with timer.alongside(name):`` on that thread) is a stage of its own,
marked ``alongside``: its wall seconds overlap the other stages', and are not part of their sum. A compilation
counts in the stage of the thread that asked for it — the stage is a context variable, which the thread pools of
:mod:`nnphd.parallel` carry to their threads (:func:`nnphd.parallel.as_here`); a thread without one counts in the
run's current stage.
"""

from __future__ import annotations

import contextvars
import threading
import time
from contextlib import contextmanager

# JAX's own duration events of a compilation (jax.monitoring; jax._src.dispatch and jax._src.interpreters.pxla):
# trace to a jaxpr, lower to MLIR, compile with XLA — the last one wraps compile_or_get_cached, so on a hit of the
# persistent compilation cache it is the retrieval
COMPILE_PARTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "xla",
}
COMPILE_EVENTS = frozenset(COMPILE_PARTS)
CACHE_RETRIEVAL_EVENT = "/jax/compilation_cache/cache_retrieval_time_sec"  # part of "xla" already: shown, not added
_STAGE: contextvars.ContextVar[str | None] = contextvars.ContextVar("nnphd_stage", default=None)


class StageTimer:
    """Wall and compile seconds per stage of one run (see the module docstring)."""

    def __init__(self) -> None:
        self.wall: dict[str, float] = {}
        self.compile: dict[str, float] = {}
        self.parts: dict[str, float] = {}  # compile seconds by kind (COMPILE_PARTS), over the whole run
        self._stack: list[tuple[str, float]] = []
        self._t0 = time.perf_counter()
        self._end: float | None = None
        self._listening = False
        self._before = 0.0  # seconds measured elsewhere (add), part of the run
        self._alongside: set[str] = set()  # stages run on another thread, beside the others
        self._lock = threading.Lock()  # compilations are reported by the threads that ask for them

    # the listener: jax calls it with (event, seconds, **metadata)
    def _on_event(self, event: str, duration: float, **_kw) -> None:
        if event in COMPILE_EVENTS:
            name = _STAGE.get() or (self._stack[-1][0] if self._stack else "other")
            part = COMPILE_PARTS[event]
            with self._lock:
                self.compile[name] = self.compile.get(name, 0.0) + float(duration)
                self.parts[part] = self.parts.get(part, 0.0) + float(duration)
        elif event == CACHE_RETRIEVAL_EVENT:
            with self._lock:
                self.parts["cache"] = self.parts.get("cache", 0.0) + float(duration)

    def __enter__(self) -> StageTimer:
        import jax.monitoring

        jax.monitoring.register_event_duration_secs_listener(self._on_event)
        self._listening = True
        self._t0 = time.perf_counter()
        return self

    def __exit__(self, *exc) -> None:
        import jax.monitoring

        self._end = time.perf_counter()
        if self._listening:
            jax.monitoring.unregister_event_duration_listener(self._on_event)
            self._listening = False

    @contextmanager
    def stage(self, name: str):
        now = time.perf_counter()
        if self._stack:  # the outer stage pauses: its time so far is its own
            outer, since = self._stack[-1]
            self.wall[outer] = self.wall.get(outer, 0.0) + now - since
        self._stack.append((name, now))
        token = _STAGE.set(name)
        try:
            yield
        finally:
            _STAGE.reset(token)
            end = time.perf_counter()
            _, since = self._stack.pop()
            self.wall[name] = self.wall.get(name, 0.0) + end - since
            if self._stack:  # the outer stage resumes
                self._stack[-1] = (self._stack[-1][0], end)

    @contextmanager
    def alongside(self, name: str):
        """A stage run on another thread, beside the run's own stages (enter it on that thread): its wall seconds
        and the compilations of its thread (and of the pools it starts, :func:`nnphd.parallel.as_here`)."""
        t0 = time.perf_counter()
        self._alongside.add(name)
        token = _STAGE.set(name)
        try:
            yield
        finally:
            _STAGE.reset(token)
            self.wall[name] = self.wall.get(name, 0.0) + time.perf_counter() - t0

    def add(self, name: str, seconds: float) -> None:
        """Wall seconds of a stage measured elsewhere (e.g. reading the file before the run began): they count in
        the total too."""
        self.wall[name] = self.wall.get(name, 0.0) + float(seconds)
        self._before += float(seconds)

    def to_dict(self) -> dict:
        """{"total_s", "compile_s", "compile_parts_s" (trace: to a jaxpr, lower: to MLIR — both also on a hit of
        the persistent cache —, xla: the XLA compilation or the retrieval from the persistent cache; cache: of xla,
        the retrieval), "stages":
        [{"stage", "s", "compile_s"}] in the order they first ran (a stage run beside the others, :meth:`alongside`,
        marked ``"alongside": True``), "other_s" (the run's time in no stage), "note"}."""
        end = self._end if self._end is not None else time.perf_counter()
        total = end - self._t0 + self._before
        names = list(dict.fromkeys([*self.wall, *self.compile]))
        stages = [
            {"stage": n, "s": self.wall.get(n, 0.0), "compile_s": self.compile.get(n, 0.0)}
            | ({"alongside": True} if n in self._alongside else {})
            for n in names
            if n != "other"
        ]
        return {
            "total_s": total,
            "compile_s": sum(self.compile.values()),
            "compile_parts_s": {k: self.parts.get(k, 0.0) for k in ("trace", "lower", "xla", "cache")},
            "stages": stages,
            "other_s": max(total - sum(s["s"] for s in stages if not s.get("alongside")), 0.0),
            "note": (
                "wall seconds on this machine; compile_s: JAX tracing, lowering and XLA compilation (or retrieval "
                "from the persistent compilation cache) in this process — work on other worker processes is not seen; "
                "a stage marked alongside ran on another thread beside the others: its seconds overlap theirs"
            ),
        }
