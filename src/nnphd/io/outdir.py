"""Output folders: created and checked writable before a run, and claimed by one run at a time.

:func:`claim_out_dir` takes an exclusive, non-blocking ``flock`` on the folder itself (no lock file is left behind).
The kernel drops it when the process ends, however it ends (also on SIGKILL), so a stale lock cannot block a later
run.  A second process that claims the same folder while the first holds it gets a one-line ``ValueError``.  Claims
are re-entrant within a process and released by :func:`release_out_dirs` (the command line calls it when a command
returns).  Where ``fcntl`` is missing (Windows), folders are not locked.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover  (Windows)
    fcntl = None

__all__ = ["ensure_writable_dir", "claim_out_dir", "release_out_dirs"]

_claimed: dict[str, int] = {}  # real path → open file descriptor holding the lock


def ensure_writable_dir(path: str | os.PathLike) -> Path:
    """Create ``path`` if needed and check a file can be written there; ValueError with a one-line reason if not."""
    if not str(path).strip():
        raise ValueError("--out must name a directory, got an empty string")
    p = Path(path)
    try:
        p.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".nnphd-probe-", dir=p)
        os.close(fd)
        os.unlink(tmp)
    except OSError as e:
        raise ValueError(f"--out {str(path)!r} is not a writable directory ({e.strerror or e})") from None
    return p


def claim_out_dir(path: str | os.PathLike) -> Path:
    """:func:`ensure_writable_dir`, then lock the folder for this process; ValueError if another process holds it."""
    p = ensure_writable_dir(path)
    key = os.path.realpath(p)
    if fcntl is None or key in _claimed:
        return p
    fd = os.open(key, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise ValueError(
            f"--out {str(path)!r} is in use by another nnphd run; wait for it to finish or choose another --out"
        ) from None
    _claimed[key] = fd
    return p


def release_out_dirs() -> None:
    """Release every folder this process claimed."""
    while _claimed:
        _, fd = _claimed.popitem()
        os.close(fd)  # closing the descriptor drops the flock
