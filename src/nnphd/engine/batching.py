"""Evaluate a compiled per-row function over many rows in fixed-size chunks, so memory stays bounded; and the shape
classes ("buckets") that let one compiled program serve records of many lengths.

A model evaluated on all N rows at once holds its intermediates for every row (the LNN's Hessians: a few KB per row,
tens of GB for millions of rows).  :func:`by_rows` cuts the rows into chunks of ``chunk`` rows (ROW_CHUNK, 1024),
pads the last one to the same shape, and concatenates the per-row outputs: one compiled program for records of every
length, so that a second record of another length finds the program the first one compiled in the persistent
compilation cache instead of compiling its own (with chunks of up to 16384 rows, padded below that to the next power
of two, a record cut to 80 % of its rows crossed a power of two one time in three). The padding repeats the last
row and is cut off again, so it is inert: every output row is a function of its own input row only. Training, whose
padded rows are never drawn (they cost memory only), pads to :func:`train_bucket`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ROW_BUCKET_MIN", "ROW_CHUNK", "bucket", "by_rows", "pad_rows", "train_bucket"]

ROW_CHUNK = 1024  # rows per evaluation: ~3 MB of LNN intermediates at width 64 in float64
ROW_BUCKET_MIN = 1024  # the smallest row bucket: records shorter than this share one program (and cost little)
TRAIN_ONE_CLASS = 1 << 14  # training's rows up to this many share one class (see train_bucket)
TRAIN_COARSE_MAX = 1 << 16  # and up to this many one more


def bucket(n: int, minimum: int = ROW_BUCKET_MIN) -> int:
    """The shape class of a size ``n``: the smallest power of two ≥ max(n, ``minimum``). Padding to it costs at most
    twice the work of ``n`` (nothing where the padding is never read, as in training's minibatches) and one compiled
    program per octave of record lengths."""
    n = max(int(n), int(minimum), 1)
    return 1 << (n - 1).bit_length()


def train_bucket(n: int) -> int:
    """The shape class of training's ``n`` rows: one class of :data:`TRAIN_ONE_CLASS` rows for every record up to
    that many (the command line thins a record to 5000 rows), then 4·TRAIN_ONE_CLASS up to :data:`TRAIN_COARSE_MAX`,
    then :func:`bucket`'s powers of two. Training draws its minibatches below the true count, so its padding costs
    memory only (about 1 MB of rows; beyond TRAIN_COARSE_MAX at most twice the rows'): every record of the command
    line trains with the same compiled programs (with classes 1024·4^k a record and its 80 % copy fell in two one
    time in six)."""
    b = bucket(n)
    if b > TRAIN_COARSE_MAX:
        return b
    return TRAIN_ONE_CLASS if b <= TRAIN_ONE_CLASS else TRAIN_COARSE_MAX


def pad_rows(rows, size: int):
    """Every array of ``rows`` (leading axis N ≤ ``size``) padded to ``size`` rows by repeating its last row (finite
    numbers a computation may touch but whose results are cut off or never drawn). Concrete arrays are padded with
    numpy; arrays being traced (under ``jit``/``vmap``) with jax.numpy."""
    out = []
    for r in rows:
        n = int(np.shape(r)[0])
        if n == size:
            out.append(r)
            continue
        if n > size or n == 0:
            raise ValueError(f"cannot pad {n} rows to {size}")
        try:
            a = np.asarray(r)
        except Exception:  # a tracer: pad inside the traced program
            import jax.numpy as jnp

            out.append(jnp.concatenate([r, jnp.repeat(r[-1:], size - n, axis=0)]))
            continue
        out.append(np.concatenate([a, np.repeat(a[-1:], size - n, axis=0)]))
    return tuple(out)


def by_rows(fn, params, *rows, chunk: int = ROW_CHUNK, **static):
    """``fn(params, *rows, **static)`` with every array of ``rows`` (leading axis N) split into chunks of ``chunk``
    rows (below ``chunk``: padded to the bucket of N, at most ``chunk``: with the default chunk, 1024 rows, every
    record's calls have one shape); returns numpy arrays (a tuple if ``fn``
    returns one), each with leading axis N. ``fn`` must compute every output row from its own input row only."""
    n = int(np.shape(rows[0])[0])
    size = min(bucket(n), chunk) if n <= chunk else chunk
    pad = -n % size
    padded = pad_rows(rows, n + pad) if pad else tuple(np.asarray(r) for r in rows)
    parts = [fn(params, *(r[i : i + size] for r in padded), **static) for i in range(0, n + pad, size)]
    if isinstance(parts[0], tuple):
        return tuple(np.concatenate([np.asarray(p[k]) for p in parts])[:n] for k in range(len(parts[0])))
    return np.concatenate([np.asarray(p) for p in parts])[:n]
