r"""The amplitude envelope of a damped oscillation — the picture physicists use to tell friction laws apart — measured
from the record (:func:`measured_envelope`) and predicted by a candidate law (:func:`predicted_envelope`).

Measured: the half swings between successive turning points (where the estimated velocity changes sign), each at
the midpoint time; swings below :data:`MIN_SWING_SIGMA`·σ (noise, a body at rest) are dropped.

Predicted (one coordinate, energy balance over one cycle of the harmonic motion q = q₀ + A cos φ, q̇ = −Aω sin φ):

    dA/dt = ⟨g(q, q̇, t)·q̇⟩_φ / (ω² A),

so viscous −γq̇ gives A' = −γA/2 (exponential: a straight line on a log axis), dry −μ sign(q̇) gives A' = −2μ/(πω)
(linear: the log curve bends down), quadratic −c|q̇|q̇ gives A' = −(4/3π) c ω A² (≈ 1/(1 + βt): the log curve bends
up), mixed laws the sums. Integrated from the first measured amplitude (RK4 on the measured times); it stops at
A = 0 (dry friction ends the motion in finite time); a law that cannot be integrated leaves NaN from there on.
"""

from __future__ import annotations

import numpy as np

__all__ = ["measured_envelope", "predicted_envelope"]

MIN_SWING_SIGMA = 6.0
N_PHASE = 64  # points of the cycle average


def measured_envelope(q, qd, t, traj, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_mid, A, trajectory id) of the half swings of one coordinate q (N,) with velocity qd (N,)."""
    q, qd, t, traj = (np.asarray(a) for a in (q, qd, t, traj))
    out_t, out_a, out_k = [], [], []
    cuts = np.flatnonzero(np.diff(traj) != 0) + 1
    for seg in np.split(np.arange(len(t)), cuts):
        s = np.sign(qd[seg])
        turn = np.flatnonzero((s[1:] * s[:-1]) < 0) + 1  # the first row after each sign change
        for a, b in zip(turn[:-1], turn[1:]):
            i, j = seg[a], seg[b]
            swing = abs(q[j] - q[i])
            if swing >= MIN_SWING_SIGMA * sigma:
                out_t.append(0.5 * (t[i] + t[j]))
                out_a.append(0.5 * swing)
                out_k.append(traj[i])
    return np.asarray(out_t, float), np.asarray(out_a, float), np.asarray(out_k)


def _rate(law, A: float, q0: float, omega: float, t: float) -> float:
    """dA/dt of the cycle-averaged energy balance at amplitude A."""
    if A <= 0:
        return 0.0
    phi = (np.arange(N_PHASE) + 0.5) * (2 * np.pi / N_PHASE)
    q = q0 + A * np.cos(phi)
    v = -A * omega * np.sin(phi)
    with np.errstate(all="ignore"):  # a candidate's law may overflow at a trial amplitude: that rate is NaN
        g = np.asarray(law(q[:, None], v[:, None], np.full(N_PHASE, t)), float)[:, 0]
        return float(np.mean(g * v) / (omega**2 * A))


def predicted_envelope(law, t, A0: float, q0: float, omega: float) -> np.ndarray:
    """A(t) at the times t (increasing; t[0] the start, A(t[0]) = A0) under ``law(q, qd, t)`` → (N, 1) (one
    coordinate), oscillating at angular frequency omega about q0; RK4 with ≥ 20 steps per interval of t, no
    negative amplitude."""
    t = np.asarray(t, float)
    A = np.empty(len(t))
    A[0] = a = float(A0)
    for k in range(1, len(t)):
        h_total = t[k] - t[k - 1]
        m = max(20, int(np.ceil(20 * h_total * omega / (2 * np.pi))))
        h = h_total / m
        tt = t[k - 1]
        for _ in range(m):
            if a <= 0:
                break
            k1 = _rate(law, a, q0, omega, tt)
            k2 = _rate(law, max(a + 0.5 * h * k1, 0.0), q0, omega, tt + 0.5 * h)
            k3 = _rate(law, max(a + 0.5 * h * k2, 0.0), q0, omega, tt + 0.5 * h)
            k4 = _rate(law, max(a + h * k3, 0.0), q0, omega, tt + h)
            a = max(a + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), 0.0)
            if not np.isfinite(a):
                A[k:] = np.nan  # the law cannot be integrated from here: no envelope
                return A
            tt += h
        A[k] = a
    return A


def envelope_report(rows, q, qd, t, traj, sigma: float, period: float, limit: int = 4) -> dict | None:
    """The measured envelope of one coordinate and the envelope each of the first ``limit`` candidate laws of
    ``rows`` (LawFit, best first; the zero law skipped) predicts, per trajectory from its first measured
    amplitude; with each one's rms log-error against the measured amplitudes (JSON-ready). None without ≥ 4 half
    swings or a finite period."""
    if not np.isfinite(period) or period <= 0:
        return None
    q, qd, t, traj = (np.asarray(a) for a in (q, qd, t, traj))
    tm, A, k = measured_envelope(q, qd, t, traj, sigma)
    if len(A) < 4:
        return None
    centres = []
    cuts = np.flatnonzero(np.diff(traj) != 0) + 1
    for seg in np.split(np.arange(len(t)), cuts):
        s = np.sign(qd[seg])
        turn = seg[np.flatnonzero((s[1:] * s[:-1]) < 0) + 1]
        centres += [0.5 * (q[i] + q[j]) for i, j in zip(turn[:-1], turn[1:])]
    q0 = float(np.median(centres))
    omega = 2 * np.pi / period
    out = {
        "measured": {"t": tm.tolist(), "A": A.tolist(), "traj": [int(x) for x in k]},
        "omega": omega,
        "q0": q0,
        "candidates": [],
    }
    for r in [r for r in rows if r.family is not None][:limit]:
        pred = np.empty_like(A)
        for kk in np.unique(k):
            m = k == kk
            pred[m] = predicted_envelope(lambda a, b, c, r=r: r.predict(a, b, c), tm[m], A[m][0], q0, omega)
        ok = np.isfinite(pred) & (pred > 0)
        err = float(np.sqrt(np.mean(np.log(pred[ok] / A[ok]) ** 2))) if ok.sum() >= 2 else float("nan")
        out["candidates"].append({"law": r.key, "title": r.title, "A": pred.tolist(), "rms_log_error": err})
    return out
