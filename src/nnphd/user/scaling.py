"""Standardised units, time features, trajectories and hold-out for :func:`nnphd.user.assess.assess` (no training).

q' = (q − μ_q)/s_q per coordinate and t' = (t − t₀)/s_t (:class:`Scaling`); angles keep their radians. Time enters the
free networks as τ = t'/std(t') plus Fourier features (:func:`time_features`). Rows are grouped into trajectories
(:func:`segments`) and whole trajectories are held out (:func:`holdout`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from nnphd.engine.data import Dataset

__all__ = ["Scaling", "fit_scaling", "time_features", "padded_time_features", "segments", "holdout", "oscillations"]

OMEGA_MAX = 3.0  # highest feature frequency, in units of 1/s_t
MAX_FOURIER = 24
# the width the free networks see the time features at (zero columns beyond the record's own 1 + 2J): the number of
# frequencies J follows the record's span, and a network of another input width is another compiled trainer — a
# second file of another length compiled it again (4 s of XLA on a 2-D drag record cut to 80 %)
TIME_FEATURE_WIDTH = 1 + 2 * MAX_FOURIER


# ------------------------------------------------------------------------------------------------------------------
# standardisation


@dataclass(frozen=True)
class Scaling:
    """q' = (q − mu_q)/s_q, t' = (t − t0)/s_t; hence q̇' = q̇ s_t/s_q and q̈' = q̈ s_t²/s_q."""

    mu_q: np.ndarray
    s_q: np.ndarray
    t0: float
    s_t: float

    def apply(self, data: Dataset):
        """(q', q̇', t', q̈') of a data set."""
        q = (data.q - self.mu_q) / self.s_q
        qd = data.qd * self.s_t / self.s_q
        qdd = data.qdd * self.s_t**2 / self.s_q
        return q, qd, (data.t - self.t0) / self.s_t, qdd

    def force_back(self, f):
        """An acceleration in model units → original units."""
        return np.asarray(f) * self.s_q / self.s_t**2

    def to_dict(self) -> dict:
        return {"mu_q": self.mu_q.tolist(), "s_q": self.s_q.tolist(), "t0": self.t0, "s_t": self.s_t}


def fit_scaling(data: Dataset, is_angle=None) -> Scaling:
    """Per-coordinate mean/std of q; s_t = geometric mean of s_q/rms(q̇) and √(s_q/rms(q̈)) over coordinates.

    Angles (``is_angle``, (n,) bools) keep their radians (shift 0, scale 1): they enter the networks as sin, cos.
    """
    q, qd, qdd = data.q, data.qd, data.qdd
    mu = q.mean(axis=0)
    s_q = q.std(axis=0)
    s_q = np.where((s_q > 0) & (s_q > 1e-12 * np.abs(mu)), s_q, 1.0)  # relative: units must not matter
    if is_angle is not None:
        ang = np.asarray(is_angle, bool)
        mu = np.where(ang, 0.0, mu)
        s_q = np.where(ang, 1.0, s_q)
    rms_v = np.sqrt(np.mean(qd**2, axis=0))
    rms_a = np.sqrt(np.mean(qdd**2, axis=0))
    logs = [np.log(s_q[i] / rms_v[i]) for i in range(data.n) if rms_v[i] > 0]
    logs += [0.5 * np.log(s_q[i] / rms_a[i]) for i in range(data.n) if rms_a[i] > 0]
    s_t = float(np.exp(np.mean(logs))) if logs else 1.0
    return Scaling(mu, s_q, float(np.mean(data.t)), s_t)


def time_features(
    tp, span: float, omega_max: float = OMEGA_MAX, max_terms: int = MAX_FOURIER, oversample: int = 1
) -> np.ndarray:
    """Time inputs from t' (N,): [t'/std, sin(ω_j t'), cos(ω_j t')], ω_j = 2πj/(oversample·span) ≤ omega_max."""
    tp = np.asarray(tp, float)
    sd = float(np.std(tp)) or 1.0
    span = max(float(span), 1e-12) * oversample
    J = int(min(max_terms * oversample, max(1, math.floor(omega_max * span / (2 * np.pi)))))
    w = 2 * np.pi * np.arange(1, J + 1) / span
    return np.concatenate([tp[:, None] / sd, np.sin(tp[:, None] * w), np.cos(tp[:, None] * w)], axis=1)


def padded_time_features(feats) -> np.ndarray:
    """``feats`` (N, k) with zero columns appended up to :data:`TIME_FEATURE_WIDTH` (k = 0, no time input, stays 0).
    A network whose first-layer weights of these columns start at zero (:func:`nnphd.engine.models.widen_inputs`)
    computes what it computes without them, and learns nothing on them (their gradients are zero, so are Adam's
    steps): the padding is inert, and every record's time features share one shape."""
    feats = np.asarray(feats, float)
    k = feats.shape[1]
    if k == 0 or k >= TIME_FEATURE_WIDTH:
        return feats
    return np.concatenate([feats, np.zeros((feats.shape[0], TIME_FEATURE_WIDTH - k))], axis=1)


# ------------------------------------------------------------------------------------------------------------------
# trajectories and hold-out


def segments(traj, t) -> list[np.ndarray]:
    """Row indices of each trajectory (ids in order of first appearance), each sorted by t."""
    t = np.asarray(t)
    if traj is None:
        return [np.argsort(t, kind="stable")]
    traj = np.asarray(traj)
    if traj.shape != t.shape:
        raise ValueError(f"traj must have one id per row, shape {t.shape}, got {traj.shape}")
    out = []
    for k in dict.fromkeys(traj.tolist()):
        idx = np.flatnonzero(traj == k)
        out.append(idx[np.argsort(t[idx], kind="stable")])
    return out


def holdout(segs: list[np.ndarray], frac: float, rng) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Hold out whole trajectories (round(frac·K), at least 1, at most K−1), or the last ``frac`` of a single one."""
    if len(segs) >= 2:
        k = min(max(1, int(round(frac * len(segs)))), len(segs) - 1)
        pick = set(rng.choice(len(segs), size=k, replace=False).tolist())
        return [s for i, s in enumerate(segs) if i not in pick], [s for i, s in enumerate(segs) if i in pick]
    s = segs[0]
    cut = int(round((1 - frac) * len(s)))
    return [s[:cut]], [s[cut:]]


def oscillations(x, segs) -> np.ndarray:
    """Per segment: the largest number of oscillations (mean crossings / 2) of any column of x (N, k)."""
    x = np.asarray(x, float)
    x = x[:, None] if x.ndim == 1 else x
    out = []
    for s in segs:
        xs = x[s] - x[s].mean(axis=0)
        sgn = np.sign(xs)
        out.append(float(np.max(np.sum(sgn[1:] * sgn[:-1] < 0, axis=0))) / 2.0 if len(s) > 1 else 0.0)
    return np.asarray(out)


# ------------------------------------------------------------------------------------------------------------------
# evidence from model units to the file's


def trend_units(tr: dict, sc: Scaling) -> dict:
    """Energy-trend rates from model time units to the file's."""
    out = dict(tr)
    for k in ("rate", "se", "kinetic_rate", "kinetic_se", "energy_rate", "energy_se"):
        if k in out and out[k] is not None and np.isfinite(out[k]):
            out[k] = out[k] / sc.s_t
    out["period"] = tr["period"] * sc.s_t
    out["block_t"] = [[sc.t0 + x * sc.s_t for x in b] for b in tr.get("block_t", [])]
    return out


def shoot_units(sh: dict, sc: Scaling) -> dict:
    out = dict(sh)
    if not sh.get("valid"):
        return out
    for k in ("d", "se_d"):
        out[k] = [x / sc.s_t for x in sh[k]]
    for k in ("d_mean", "se_d_mean", "se_d_mean_model", "se_d_mean_jackknife"):
        out[k] = sh[k] / sc.s_t
    out["rms_residual"] = [x * s for x, s in zip(sh["rms_residual"], sc.s_q)]
    return out
