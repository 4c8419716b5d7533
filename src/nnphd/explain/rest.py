r"""Stretches of a record at rest (:func:`rest_mask`), and the record without them (:func:`without_rest`).

A damped real oscillator often ends stuck: dry friction holds it at rest anywhere in a dead band around its
equilibrium, and a stick-slip system sticks and restarts. At rest q̇ = q̈ = 0 while the conservative force is not zero
(the body rests off the equilibrium), and a smoothed sign(q̇) is zero there: fitted with the moving rows, a stuck
phase biases every candidate law (the conservative fit is pulled towards a false equilibrium, the dry term towards
zero). So the law fits leave the stuck stretches out and say so.

Rule: a window of :data:`REST_WINDOW_PERIODS` of the dominant period (at least :data:`REST_MIN_SAMPLES` samples; those
alone when the motion does not oscillate) is at rest when, for every coordinate,
its standard deviation is at most :data:`REST_TOL_SIGMA`·σ + ½·(quantization step) — σ the position noise (pure
noise has σ; a body flickering between two encoder steps at most ½ step). A row is at rest when a window at
rest holds it; the rows within half the q̈ estimator's window of a stuck stretch go too (their q̈ is smeared across
the jump of the force when the body sticks). Moving pieces shorter than :data:`MIN_PIECE` rows are dropped. In any
window of ½ period of an oscillation of amplitude A the standard deviation is ≥ 0.31·A (the least, centred on a
turning point), so motion of amplitude ≳ 5σ is never rest; a stick shorter than ½ period is not found.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from nnphd.explain.jointfit import trajectory_segments

__all__ = ["rest_mask", "without_rest"]

REST_WINDOW_PERIODS = 0.5
REST_MIN_SAMPLES = 5
REST_TOL_SIGMA = 1.5
MIN_PIECE = 12


def rest_mask(q, t, traj, sigma, step=None, period: float = np.inf, margin: int = 0) -> np.ndarray:
    """(N,) booleans: the rows at rest (see the module docstring). q (N, n) positions, t (N,), traj (N,) ids
    (rows of a trajectory contiguous), sigma (n,) the position noise, step (n,) the quantization steps (0: none),
    period the dominant period (inf: no oscillation), margin the rows around a stuck stretch that go with it."""
    q, t, traj = np.asarray(q, float), np.asarray(t, float), np.asarray(traj)
    N, n = q.shape
    sigma = np.asarray(sigma, float).reshape(n)
    step = np.zeros(n) if step is None else np.asarray(step, float).reshape(n)
    tol = REST_TOL_SIGMA * sigma + 0.5 * step
    tol = np.where(tol > 0, tol, 1e-12 * np.maximum(np.ptp(q, axis=0), 1e-300))
    rest = np.zeros(N, bool)
    for seg in trajectory_segments(traj):
        m = len(seg)
        dt = float(np.median(np.diff(t[seg]))) if m > 1 else 0.0
        w = REST_MIN_SAMPLES
        if np.isfinite(period) and dt > 0:
            w = max(w, int(round(REST_WINDOW_PERIODS * period / dt)))
        if m < w:
            continue
        from numpy.lib.stride_tricks import sliding_window_view

        win = sliding_window_view(q[seg], w, axis=0)  # (m - w + 1, n, w)
        still = np.all(np.std(win, axis=2) <= tol[None], axis=1)  # window k covers rows k … k + w − 1
        if not still.any():
            continue
        cover = np.convolve(still.astype(float), np.ones(w))[:m] > 0  # rows inside some window at rest
        if margin > 0:
            cover = np.convolve(cover.astype(float), np.ones(2 * margin + 1), mode="same") > 0
        rest[seg] = cover
    return rest


def without_rest(data, traj, rest: np.ndarray, extra: dict | None = None):
    """(data', traj', keep, extra'): the rows not at rest, each moving piece its own trajectory (a piece shorter
    than MIN_PIECE rows dropped); ``data`` needs q, qd, qdd, t; ``extra`` arrays (N, …) are cut alike."""
    traj = np.asarray(traj)
    keep = ~np.asarray(rest, bool)
    new_id = np.full(len(traj), -1)
    k = 0
    for seg in trajectory_segments(traj):
        piece = keep[seg]
        cuts = np.flatnonzero(np.diff(piece.astype(int)) != 0) + 1
        for run in np.split(seg, cuts):
            if keep[run[0]] and len(run) >= MIN_PIECE:
                new_id[run] = k
                k += 1
    keep = new_id >= 0
    d = SimpleNamespace(**{a: np.asarray(getattr(data, a))[keep] for a in ("q", "qd", "qdd", "t")})
    out = {a: (None if v is None else np.asarray(v)[keep]) for a, v in (extra or {}).items()}
    return d, new_id[keep], keep, out
