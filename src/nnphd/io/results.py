"""Writing results: atomic JSON and PNG files (nothing half-written), and the L_e(λ) plot."""

from __future__ import annotations

import hashlib
import json
import os
import stat
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TypeVar

import numpy as np

from nnphd.io.escape import mpl as _m
from nnphd.io.outdir import ensure_writable_dir  # noqa: F401  (re-exported: the writers' folder check)

R = TypeVar("R")  # a typed result


def json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.bool_):
        return bool(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# The files this process wrote (absolute path → device, inode, size and SHA-256 of what it wrote): a failed or
# interrupted command removes only files that are still the ones it wrote (nnphd.cli.common.undo_run), never one
# that was there before or was put there since (an inode number is reused at once, hence the contents too).
_written: dict[str, tuple[int, int, int, bytes]] = {}


def written_by_this_process(path: str | os.PathLike) -> bool:
    """Whether ``path`` is (still) the very file :func:`atomic_write_bytes` of this process wrote there: the same
    inode, holding the same bytes (read without following a link or waiting on a FIFO)."""
    key = os.path.abspath(path)
    if key not in _written:
        return False
    dev, ino, size, digest = _written[key]
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(key, flags)
    except OSError:
        return False
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fd)
        if (st.st_dev, st.st_ino, st.st_size) != (dev, ino, size) or not stat.S_ISREG(st.st_mode):
            return False
        return hashlib.sha256(fh.read(size + 1)).digest() == digest


def forget_written() -> None:
    """Forget which files this process wrote (a new command starts)."""
    _written.clear()


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path`` and rename it over ``path`` (never half-written), with the
    permissions a plain ``open`` would give (0666 less the umask; mkstemp's are 0600). The file is noted as written
    by this process (:func:`written_by_this_process`)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            st = os.fstat(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
        _written[os.path.abspath(path)] = (st.st_dev, st.st_ino, len(data), hashlib.sha256(data).digest())
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_json(path: str | os.PathLike, obj) -> None:
    atomic_write_bytes(path, (json.dumps(obj, indent=2, default=json_default, allow_nan=True) + "\n").encode())


def subplots(*args, figsize=None, **kw):
    """(fig, axes) on a bare matplotlib Figure: no pyplot, so no backend is chosen and nothing global changes (the
    library never calls ``matplotlib.use``); the figure saves to PNG and shows in a notebook as any other."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(*args, **kw)


def save_figure(fig, path: str | os.PathLike) -> None:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120, bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())


def plot_sweep(curves: dict[str, Sequence[dict]], title: str = "", show_lb: bool = True):
    """L_e(λ) (and dashed L_b(λ)) on log axes, one curve per name (plain text: "$" escaped); rows are dicts with
    lam, L_e, L_b; ``title`` may hold mathtext."""
    fig, ax = subplots(figsize=(5.5, 4))
    for i, (name, rows) in enumerate(curves.items()):
        lam = [r["lam"] for r in rows]
        color = f"C{i}"
        ax.plot(lam, [max(r["L_e"], 1e-8) for r in rows], "o-", color=color, label=f"{_m(name)}: $L_e$")
        if show_lb:
            ax.plot(
                lam,
                [max(r["L_b"], 1e-8) for r in rows],
                "s--",
                color=color,
                alpha=0.5,
                ms=3,
                label=f"{_m(name)}: $L_b$",
            )
    ax.axvline(1.0, color="k", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(r"$\lambda$")
    ax.set_ylabel("loss")
    ax.set_title(title or r"recovery error $L_e(\lambda)$")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def write_results(outdir: Path | None, result: R, figures: dict | None = None, t0: float | None = None) -> R:
    """Finish a study: draw ``figures`` (file name → a function of the result's dict returning a Figure) into
    ``outdir``, set the result's ``wall_time_s`` from ``t0`` (time.perf_counter), then write results.json, the
    result's ``to_dict()`` (last, so its presence marks a finished run). ``result`` is a typed result (a frozen
    dataclass with ``wall_time_s`` and ``to_dict()``, e.g. :class:`nnphd.paper.study_results.LambdaPResult`);
    returns it with its wall time."""
    import dataclasses
    import time

    if outdir is not None and figures:
        d = result.to_dict()
        for name, draw in figures.items():
            save_figure(draw(d), Path(outdir) / name)
    if t0 is not None:
        result = dataclasses.replace(result, wall_time_s=time.perf_counter() - t0)
    if outdir is not None:
        write_json(Path(outdir) / "results.json", result.to_dict())
    return result
