"""How a law's force works along the record: its share against the velocity (a drag's is 1, a thrust's −1), that
share per trajectory, and how much of it is a function of position (or of the state) along this record — what tells a
non-conservative force from one a learned potential can stand in for (:mod:`nnphd.user.rules` decides with them).
"""

from __future__ import annotations

import numpy as np

__all__ = ["POSITION_K", "against_velocity", "position_explained", "work_per_trajectory"]


def work_per_trajectory(f, qd, traj) -> float | None:
    """The median over trajectories of |:func:`against_velocity`| of each: how much net work the force does along a
    typical trajectory, whatever its sign there. None with one trajectory (the pooled share says it all) or where no
    trajectory moves."""
    traj = np.asarray(traj)
    if len(np.unique(traj)) < 2:
        return None
    shares = [against_velocity(np.asarray(f)[traj == k], np.asarray(qd)[traj == k]) for k in np.unique(traj)]
    shares = [abs(s) for s in shares if s is not None]
    return float(np.median(shares)) if shares else None


def against_velocity(f, qd) -> float | None:
    """Σ(−f·v̂) / Σ|f| over the rows: 1 for a force that opposes the velocity (a drag), −1 for a thrust, about 0 for
    one across it. ``f``, ``qd`` (N, n) in the record's coordinates; rows at rest (or a law that is zero) do not
    count. None when nothing moves or the force is zero."""
    f, qd = np.asarray(f, float), np.asarray(qd, float)
    speed = np.linalg.norm(qd, axis=1)
    ok = np.isfinite(speed) & (speed > 0) & np.all(np.isfinite(f), axis=1)
    size = float(np.sum(np.linalg.norm(f[ok], axis=1)))
    if not np.any(ok) or size <= 0:
        return None
    return float(-np.sum(np.einsum("ni,ni->n", f[ok], qd[ok]) / speed[ok]) / size)


POSITION_K = 8  # neighbours in position (:func:`position_explained`)


def position_explained(f, q, t, traj=None, period: float = float("nan")) -> float | None:
    """How much of the force ``f`` (N, n) on the rows is a function of ``q`` (N, m) along this record: 1 − rms(f − f̂)/
    rms(f), f̂ at each row the mean of f over its POSITION_K nearest rows in q (each column scaled by its spread)
    among those at least a quarter period away in time on its trajectory (other passes; any row of another
    trajectory). With q the positions: on one orbit that revisits its path (a planet, a satellite) each position
    comes with one velocity, so every force of the state is a force of position there (≈ 1), which a learned
    potential can absorb; on a 1-D oscillation each position comes with ±q̇, so a force odd in q̇ (a drag, a Rayleigh
    pump) is not (≈ 0). With q the states (q, q̇): whether the force is a reproducible function of the state at all —
    a law that differs at the same state on another pass (an ill-conditioned fit) is not (measured: a sparse
    polynomial fitted to a Venus orbit's model error, 0.20). None when too few neighbours qualify."""
    from scipy.spatial import cKDTree

    f, q, t = np.asarray(f, float), np.asarray(q, float), np.asarray(t, float)
    f, q = f.reshape(len(f), -1), q.reshape(len(q), -1)
    traj = np.zeros(len(t), int) if traj is None else np.asarray(traj)
    gap = 0.25 * period if np.isfinite(period) and period > 0 else 0.25 * float(np.ptp(t))
    idx = np.flatnonzero(np.all(np.isfinite(f), axis=1) & np.all(np.isfinite(q), axis=1))
    size = float(np.sqrt(np.mean(np.sum(f[idx] ** 2, axis=1)))) if len(idx) else 0.0
    if len(idx) < 2 * POSITION_K or size <= 0:
        return None
    scale = np.std(q[idx], axis=0)
    x = q[idx] / np.where(scale > 0, scale, 1.0)
    _, nb = cKDTree(x).query(x, k=min(len(idx), 8 * POSITION_K))
    rows, cand = idx[:, None], idx[nb]
    ok = (traj[cand] != traj[rows]) | (np.abs(t[cand] - t[rows]) >= gap)
    ok &= np.cumsum(ok, axis=1) <= POSITION_K  # the POSITION_K nearest that qualify
    n = ok.sum(axis=1)
    use = n > 0
    if use.sum() < len(idx) // 2:
        return None
    fhat = np.einsum("rk,rkd->rd", ok[use], f[cand[use]]) / n[use, None]
    err = float(np.mean(np.sum((f[idx[use]] - fhat) ** 2, axis=1)))
    return float(1.0 - np.sqrt(err) / size)
