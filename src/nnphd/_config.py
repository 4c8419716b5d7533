"""nnphd's process-wide settings — float64, the XLA:CPU flags, the persistent compilation cache — set by
:func:`configure` (re-exported as :func:`nnphd.configure`) in the command line, the tests, the benchmarks and every
Dask worker. A module of the lowest layer, so that :mod:`nnphd.parallel` need not import the package's front door.
Importing it changes nothing."""

from __future__ import annotations

import os
import stat
from pathlib import Path

XLA_FLAG = "--xla_cpu_experimental_ynn_fusion_type="
ONE_THREAD_FLAGS = "--xla_cpu_multi_thread_eigen=false"

COMPILE_CACHE_ENV = "NNPHD_COMPILE_CACHE"
COMPILE_CACHE_MAX_BYTES = 2**30  # least recently used programs are evicted beyond 1 GiB


class CompileCacheWarning(UserWarning):
    """The compile cache folder is not safe to load programs from (another owner, writable by others): not used."""


def default_compile_cache() -> Path:
    """The command line's compiled-program cache: ``$XDG_CACHE_HOME/nnphd/jax`` (``~/.cache/nnphd/jax``; created
    with mode 0700)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "nnphd" / "jax"


def compile_cache_dir(compile_cache: str | os.PathLike | bool | None = None) -> Path | None:
    """The folder :func:`configure` uses for ``compile_cache`` (None: off). A path is used as given; False is off;
    True and None take NNPHD_COMPILE_CACHE when it is set (a folder, or ``0``/``off``/empty for off), else True is
    :func:`default_compile_cache` and None is off."""
    if compile_cache is False:
        return None
    if compile_cache is not None and compile_cache is not True:
        return Path(compile_cache)
    env = os.environ.get(COMPILE_CACHE_ENV)
    if env is not None:
        return None if env.strip().lower() in ("", "0", "off", "no", "false") else Path(env)
    return default_compile_cache() if compile_cache else None


def configure(
    x64: bool = True,
    fast_cpu: bool = True,
    one_thread: bool = True,
    compile_cache: str | os.PathLike | bool | None = None,
) -> None:
    """Process-wide settings for nnphd's own programs (the CLI, the tests, the benchmarks, the Dask workers).

    ``x64``: turn on JAX float64 everywhere (the low-level modules, e.g. :mod:`nnphd.user.assess`, expect it).
    ``fast_cpu``: add ``--xla_cpu_experimental_ynn_fusion_type=`` to XLA_FLAGS — XLA:CPU (jax 0.10) routes small
    matrix products through YNNPACK, 1.8–2.5× slower for these models (benchmarks/bench_speed.py).
    ``one_thread``: one XLA thread (no Eigen thread pool). Eigen splits a matrix product's sums differently with
    more threads, which changes the last bits and, after thousands of training steps, the 5th digit; with one
    thread here and in every Dask worker (:mod:`nnphd.parallel`) the same seed gives the same numbers whatever the
    number of workers. More cores are used through workers; one sweep alone is as fast as with the Eigen pool on
    2 cores (``nnphd sweep --steps 500``: 16.0 and 21.4 s against 19.0 and 20.8 s, alternating runs).
    The XLA flags only take effect if JAX has not started its backend yet; NNPHD_KEEP_XLA_FLAGS=1 vetoes both.
    ``compile_cache``: a folder for JAX's persistent compilation cache (see :func:`compile_cache_dir`; True: the
    default folder, as the command line does). A program compiled once — a training step, a rollout, even a small
    eager operation — is then loaded from disk by later runs and by every Dask worker started from this process
    (the folder goes to them in NNPHD_COMPILE_CACHE) instead of compiled again: most of a short run's time is
    compilation (the tiny ``reproduce`` of the tests: 40 of 48 s). A loaded program is the compiled one, so the
    numbers are the same; at most 1 GiB is kept (least recently used evicted). Set it before the first compilation.
    JAX runs what it loads from there, so the folder must be this user's own: one owned by someone else or writable
    by group or others is not used (one :class:`CompileCacheWarning` line naming it and why; the run compiles as
    usual), and a missing folder is created with mode 0700 (:func:`compile_cache_problem`).
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if not os.environ.get("NNPHD_KEEP_XLA_FLAGS"):
        if one_thread and "multi_thread_eigen" not in flags:
            flags += " " + ONE_THREAD_FLAGS
        if fast_cpu and "ynn_fusion_type" not in flags:  # last: a flag after its empty value would be lost
            flags += " " + XLA_FLAG
        if flags.strip():
            os.environ["XLA_FLAGS"] = flags.strip()
    if x64:
        import jax

        jax.config.update("jax_enable_x64", True)
    cache = compile_cache_dir(compile_cache)
    if cache is not None:
        _use_compile_cache(cache)


def compile_cache_problem(cache: Path) -> str | None:
    """Why ``cache`` must not hold compiled programs, or None when it may: created (mode 0700, its parents as the
    umask gives) when missing; then it must be a folder (a link to one is followed) owned by this user and writable
    by nobody else — JAX loads and runs the programs it finds there, so another user who can write into it could
    make nnphd run their code. ``"cannot be created"`` (a read-only place) is a problem too, but not a warning's."""
    try:
        cache.mkdir(parents=True, exist_ok=True, mode=0o700)
        st = os.stat(cache)
    except OSError as e:
        return f"cannot be created ({e.strerror or e})"
    if not stat.S_ISDIR(st.st_mode):
        return "not a folder"
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        return f"owned by another user (uid {st.st_uid}), not by you (uid {os.getuid()})"
    if st.st_mode & 0o022:
        who = " and ".join(w for w, bit in (("group", 0o020), ("others", 0o002)) if st.st_mode & bit)
        return f"writable by {who} (mode {stat.S_IMODE(st.st_mode):o}; chmod go-w it, or choose another folder)"
    return None


def _use_compile_cache(cache: Path) -> None:
    """Point JAX's persistent compilation cache at ``cache`` if :func:`compile_cache_problem` finds none; otherwise
    compile as usual: silently where the folder cannot be created (a read-only place, as before); for an unsafe
    folder with one :class:`CompileCacheWarning` line, NNPHD_COMPILE_CACHE then set to ``0`` so the Dask workers
    started from this process skip it without a warning of their own."""
    why = compile_cache_problem(cache)
    if why is not None:
        if not why.startswith("cannot be created"):
            import warnings

            from nnphd.io.escape import one_line

            msg = one_line(f"{cache}: not used as the compile cache ({why}); compiling without it")
            warnings.warn_explicit(msg, CompileCacheWarning, "<nnphd>", 0, module=__name__)
            os.environ[COMPILE_CACHE_ENV] = "0"
        return
    import jax

    jax.config.update("jax_compilation_cache_dir", str(cache))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)  # small programs add up: cache them all
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    jax.config.update("jax_compilation_cache_max_size", COMPILE_CACHE_MAX_BYTES)
    os.environ[COMPILE_CACHE_ENV] = str(cache)  # the Dask workers started from this process use it too


# Every XLA:CPU executable JAX keeps in memory holds memory mappings, and one process may have at most
# vm.max_map_count of them (65530 by default). nnphd compiles programs per fit (closures over each record's shapes
# and settings), so one process fitting many records ran out: ~2400 mappings per small `detect` run kept for good,
# and after ~15 default runs XLA failed with "LLVM compilation error: Cannot allocate memory" and the process
# crashed (segfault) — a batch, a benchmark or a notebook fitting file after file. Above this share of the limit
# the in-memory compiled programs are dropped (the persistent compilation cache keeps them on disk).
MAP_SHARE_MAX = 0.5


def mapped_regions() -> tuple[int, int] | None:
    """(memory mappings of this process, the system's limit vm.max_map_count), or None where /proc has neither."""
    try:
        with open("/proc/sys/vm/max_map_count") as f:
            limit = int(f.read().strip())
        with open("/proc/self/maps", "rb") as f:
            used = sum(1 for _ in f)
    except (OSError, ValueError):
        return None
    return used, limit


def release_compiled_if_crowded(share: float | None = None) -> bool:
    """Drop JAX's in-memory compiled programs (``jax.clear_caches``) when this process holds more than ``share``
    (default :data:`MAP_SHARE_MAX`) of the memory mappings it may hold; True if it did. Called before each fit and each seed, it keeps a long-lived
    process from crashing; it costs the next fit its in-memory cache (your own jitted functions recompile once)."""
    counts = mapped_regions()
    if counts is None or counts[0] <= (MAP_SHARE_MAX if share is None else share) * counts[1]:
        return False
    import gc

    import jax

    jax.clear_caches()
    gc.collect()
    return True
