"""Evaluate a compiled per-row function over many rows in fixed-size chunks, so memory stays bounded.

A model evaluated on all N rows at once holds its intermediates for every row (the LNN's Hessians: a few KB per row,
tens of GB for millions of rows).  :func:`by_rows` cuts the rows into chunks of ``chunk`` rows, pads the last one to
the same shape (one compilation), and concatenates the per-row outputs.  Up to ``chunk`` rows it is the plain call.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ROW_CHUNK", "by_rows"]

ROW_CHUNK = 16384  # rows per evaluation: ~50 MB of LNN intermediates at width 64 in float64


def by_rows(fn, params, *rows, chunk: int = ROW_CHUNK, **static):
    """``fn(params, *rows, **static)`` with every array of ``rows`` (leading axis N) split into chunks of ``chunk``
    rows; returns numpy arrays (a tuple if ``fn`` returns one), each with leading axis N."""
    n = int(np.shape(rows[0])[0])
    if n <= chunk:
        out = fn(params, *rows, **static)
        return tuple(np.asarray(x) for x in out) if isinstance(out, tuple) else np.asarray(out)
    pad = -n % chunk
    padded = [np.concatenate([r, np.repeat(np.asarray(r)[-1:], pad, axis=0)]) if pad else np.asarray(r) for r in rows]
    parts = [fn(params, *(r[i : i + chunk] for r in padded), **static) for i in range(0, n + pad, chunk)]
    if isinstance(parts[0], tuple):
        return tuple(np.concatenate([np.asarray(p[k]) for p in parts])[:n] for k in range(len(parts[0])))
    return np.concatenate([np.asarray(p) for p in parts])[:n]
