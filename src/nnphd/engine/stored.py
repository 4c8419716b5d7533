"""Compiled programs traced and lowered once per machine, not once per process: the hottest programs (the shooting
residuals and derivatives of the law fits and of the detection's damping probe) are exported with
:mod:`jax.export` to a folder beside JAX's persistent compilation cache and read back by the next process, which
then skips tracing and lowering (~1–2 s per program, ~10 s of a video pendulum's run) and finds the XLA executable
in the compilation cache.

A program is stored under a key of everything it is built from: its name, a description of what its Python
closes over (``key``, a string given by the caller — None where it cannot be described, e.g. a law of the user's:
then it is compiled as usual), its arguments' shapes, dtypes and structure, the versions of JAX and jaxlib, the
float64 setting, the backend and a fingerprint of nnphd's own source (another version of nnphd never reads this
one's programs). A stored file is data, not code (a flatbuffer with StableHLO, parsed by JAX — never unpickled);
one that cannot be read, that is larger than :data:`MAX_BYTES` or whose inputs are not the call's is ignored and
written again. The folder holds at most :data:`MAX_FILES` programs (the least recently written go first).

Without a compilation cache (``nnphd.configure(compile_cache=False)``, NNPHD_COMPILE_CACHE=0), with
NNPHD_STORED_PROGRAMS=0 or without the ``flatbuffers`` package that serialization needs, every program is compiled
as usual. Storing costs a process that compiles a program ~0.1–0.5 s more (the stored program is lowered once more
to be run): the fast test tier, whose processes compile hundreds of small programs once each, turns it off. The numbers are the same:
the exported program is the one :func:`jax.jit` lowers (tests/test_stored_programs.py).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

import jax

ENV = "NNPHD_STORED_PROGRAMS"  # 0/off: compile every program as usual (the fast test tier: tests/conftest.py)
MAX_BYTES = 64 * 2**20  # a stored program larger than this is not read (the largest here: ~0.1 MB)
MAX_FILES = 2000
FOLDER = "nnphd-exported"
_SUFFIX = ".jaxexport"

_memo: dict = {}  # (name, key, structure, shapes) → the callable program, in this process
_locks: dict = {}
_lock = threading.Lock()
_fingerprint: str | None = None


def source_fingerprint() -> str:
    """sha256 of nnphd's own source files (every .py of the package, by relative path): another version of the
    code never runs this one's stored programs."""
    global _fingerprint
    if _fingerprint is None:
        root = Path(__file__).resolve().parent.parent
        h = hashlib.sha256()
        for p in sorted(root.rglob("*.py")):
            h.update(str(p.relative_to(root)).encode() + b"\0")
            h.update(p.read_bytes() + b"\0")
        _fingerprint = h.hexdigest()
    return _fingerprint


def folder() -> Path | None:
    """Where the programs are stored: ``nnphd-exported`` inside JAX's persistent compilation cache folder (None:
    no cache configured, NNPHD_STORED_PROGRAMS=0, or no ``flatbuffers``)."""
    cache = jax.config.jax_compilation_cache_dir
    if not cache or os.environ.get(ENV, "").strip().lower() in ("0", "off", "no", "false"):
        return None
    try:
        import flatbuffers  # noqa: F401 — what jax.export's serialization needs
    except ImportError:
        return None
    return Path(cache) / FOLDER


def _avals(leaves) -> tuple:
    return tuple((tuple(int(d) for d in jax.numpy.shape(x)), str(jax.numpy.result_type(x))) for x in leaves)


def run(name: str, fun: Callable, key: str | None, args: tuple):
    """``fun(*args)`` compiled: from the program stored for (``name``, ``key``, the arguments' shapes) where there
    is one, else exported and stored for the next process; with no folder (:func:`folder`), ``key`` None or traced
    arguments, by ``jax.jit(fun)`` as usual. ``fun`` must be a pure function of the array pytree ``args`` whose every other input
    ``key`` describes (see the module docstring)."""
    leaves, tree = jax.tree_util.tree_flatten(args)
    # inside a transformation (a λ-sweep vmapped over the trainer): jax.jit, which every transformation goes through
    # (an exported program has no batching rule)
    traced = any(isinstance(x, jax.core.Tracer) for x in leaves)
    where = folder() if key is not None and not traced else None
    mk = (name, key, str(tree), _avals(leaves), where is not None)
    prog = _memo.get(mk)
    if prog is None:
        with _lock:
            lock = _locks.setdefault(mk, threading.Lock())
        with lock:  # threads asking for the same program wait for the first one's
            prog = _memo.get(mk)
            if prog is None:
                prog = _program(fun, tree, leaves, where, _disk_key(name, key, tree, leaves) if where else None)
                _memo[mk] = prog
    return prog(*leaves)


def _disk_key(name, key, tree, leaves) -> str:
    text = json.dumps(
        [
            name,
            key,
            str(tree),
            _avals(leaves),
            jax.__version__,
            _jaxlib_version(),
            bool(jax.config.jax_enable_x64),
            jax.default_backend(),
            source_fingerprint(),
        ]  # fmt: skip
    )
    return hashlib.sha256(text.encode()).hexdigest()


def _jaxlib_version() -> str:
    try:
        import jaxlib

        return str(jaxlib.__version__)
    except Exception:  # noqa: BLE001 — the key only needs something stable
        return "?"


def _program(fun, tree, leaves, where: Path | None, disk_key: str | None) -> Callable:
    def flat(*xs):
        return fun(*jax.tree_util.tree_unflatten(tree, xs))

    if where is None:
        return jax.jit(flat)
    from jax import export

    path = where / (disk_key + _SUFFIX)
    exp = _read(path, leaves)
    if exp is None:
        exp = export.export(jax.jit(flat))(*leaves)
        _write(path, exp.serialize())
    return jax.jit(exp.call)


def _read(path: Path, leaves):
    """The stored program at ``path`` if it is one for these arguments, else None (a damaged or foreign file is
    ignored: written again by the caller)."""
    from jax import export

    try:
        if not path.is_file() or path.stat().st_size > MAX_BYTES:
            return None
        exp = export.deserialize(bytearray(path.read_bytes()))
        want = _avals(leaves)
        got = tuple((tuple(int(d) for d in a.shape), str(a.dtype)) for a in exp.in_avals)
        if got != want or exp.nr_devices != 1:
            return None
        return exp
    except Exception:  # noqa: BLE001 — anything a damaged file raises in the parser means "not stored"
        return None


def _write(path: Path, data: bytes | bytearray) -> None:
    """Write ``data`` to ``path`` whole or not at all (a temporary file renamed); a folder that cannot be written
    is a program not stored, never an error."""
    try:
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        _trim(path.parent)
    except OSError:
        return


def _trim(where: Path) -> None:
    files = list(where.glob("*" + _SUFFIX))
    if len(files) <= MAX_FILES:
        return
    files.sort(key=lambda p: p.stat().st_mtime)
    for p in files[: len(files) - MAX_FILES]:
        p.unlink(missing_ok=True)


def clear_memo() -> None:
    """Forget the programs of this process (the stored ones stay): the next call reads or exports them again."""
    with _lock:
        _memo.clear()
        _locks.clear()
