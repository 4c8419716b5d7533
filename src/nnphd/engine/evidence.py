r"""Evidence that accumulates over the whole record: the energy trend of the learned Lagrangian and a multiple-shooting
fit of the positions.

Why. On a real recording the non-conservative force is often ~1 % of the total force while the pointwise q̈
estimated from positions has a ~5 % error, so every pointwise loss (the paper's L_e(λ), a fit gap) is blind to it.
Its *effect* adds up along the trajectory: a pendulum that loses 1 % of its force to friction loses 64 % of its
energy over 16 swings. Two statistics read that effect, both from a conservative model (the LNN fitted pointwise):

1. **Energy trend** (:func:`energy_trend`). The learned energy H = q̇·∂L/∂q̇ − L is a function of the state; on
   recurrent conservative motion its average over one oscillation period is the same in every period however badly
   the LNN fits, so a trend of the per-period means is non-conservation. Per trajectory the record is cut into
   blocks of one period (by time; the last partial block is dropped), y_k = log(⟨H⟩_k − H_min) with H_min the learned
   energy at rest at the lowest point of the data (H(q, 0) minimised over the rows), regressed on the block times
   with one intercept per trajectory and a common slope −r: r is the relative energy-decay rate (1/time; for linear
   damping −γq̇ of an oscillator r ≈ γ). Its standard error comes from the residual scatter of the blocks, inflated
   by √((1+ρ₁)/(1−ρ₁)) for their lag-1 autocorrelation ρ₁ ≥ 0; z = r / se.
2. **Multiple shooting** (:func:`nnphd.engine.shooting.shooting_fit`). The positions are cut into windows of ≈ 0.75 oscillation periods
   (so successive windows start at phases 0, 270, 180, 90°, …, which cancels phase-locked biases), each window's
   initial state (q₀, q̇₀) is free, and the model q̈ = (1 + c)·f_c(q, q̇) − D q̇ is integrated through each window by
   RK4 at the recorded times (sub-stepped) and fitted to the recorded positions (weighted by the position noise) by
   Levenberg–Marquardt. c (a common time-scale correction of the conservative model: for a Lagrangian T(q, q̇) − V(q)
   with T quadratic in q̇, (1 + c)·f_c is the same system on a rescaled clock, so it stays conservative) is a
   nuisance; D = diag(d) is the probe of the non-conservative force. The per-window initial states are eliminated
   (Schur complement), so the normal equations of (c, d) are sums of per-window terms; that makes a
   delete-a-group jackknife over windows (and a bootstrap over windows) one linear solve each. se(d) is the larger of
   the jackknife and the model-based (reduced-χ² scaled) standard error; z = d̄ / se(d̄) for the kinetic-energy
   weighted mean d̄ of d (with d in 1/time, energy decays at ≈ d̄).

Window length and noise: the windows are ≈ 0.75 of the dominant period (from mean crossings of q and q̇, swings within
the position noise not counted), at least ``MIN_WINDOW`` and at most ``MAX_WINDOW`` samples; the residuals are
weighted by the estimated position noise of each coordinate (floored at 1e-3 of its spread, for noise-free data).
Motion that does not oscillate (a throw, a fall) has no period: both statistics then use blocks of 1/NONOSC_BLOCKS of
the record (:func:`evidence_block`), a trend is per block, and its absence proves little — a conservative potential
can be shaped to follow a path that never returns to its states.

Both statistics are computed in the standardised units of :mod:`nnphd.user.assess` and reported in the file's units.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "dominant_period",
    "evidence_block",
    "velocity_time_scale",
    "energy_trend",
    "percent_per_period",
    "period_blocks",
]

MIN_BLOCKS = 4  # energy trend: at least this many whole periods in all (and 2 per trajectory used)
RESOLVED_SNR = 3.0  # dominant_period: a column's swing must reach this many position-noise σ to count as oscillating
NONOSC_BLOCKS = 8  # motion that does not oscillate: blocks (and shooting windows) of 1/NONOSC_BLOCKS of the record


# ------------------------------------------------------------------------------------------------------------------
# periods and blocks


CROSSING_HYSTERESIS = 0.1  # dominant_period: a crossing counts once the column has gone this far beyond its mean on the
# other side, as a share of its swing's rms (the 95th percentile of |y| / √2: a sine's rms, not diluted by a stretch
# at rest) — the noise of a body at rest (its velocity flickering about zero) or the slow turn of a long swing
# crosses the mean again and again (a dry-friction record read 0.71 s for its 1.5 s period, a seismometer 4.8 s for
# ~15 s)


def _crossings(y: np.ndarray) -> np.ndarray:
    """Indices i where y (mean 0) crosses zero between i and i + 1 — only the last crossing before y reaches
    ±CROSSING_HYSTERESIS times its swing's rms on the other side (a Schmitt trigger)."""
    h = CROSSING_HYSTERESIS * float(np.percentile(np.abs(y), 95)) / math.sqrt(2)  # = share × rms for a sine
    state = np.where(y > h, 1, np.where(y < -h, -1, 0))
    idx = np.flatnonzero(state)
    if len(idx) < 2:
        return np.zeros(0, int)
    flips = idx[1:][state[idx[1:]] != state[idx[:-1]]]  # first sample beyond the threshold on the new side
    zc = np.flatnonzero(np.sign(y[1:]) * np.sign(y[:-1]) <= 0)
    zc = zc[(y[zc] != y[zc + 1])]
    pos = np.searchsorted(zc, flips) - 1  # the last zero crossing before each flip
    return zc[pos[pos >= 0]]


def dominant_period(x, t, segs, position_noise=None) -> float:
    """Time of one oscillation of the column of x (N, k) that oscillates most: twice the mean time between
    consecutive crossings of its mean (crossing times interpolated linearly; from the first to the last crossing of
    each segment, so the partial oscillations at the ends do not bias it). inf if nothing oscillates.

    ``position_noise`` (n,), optional, with x = [q, q̇] (k = 2n columns): a column whose swing is not resolved
    above the position noise does not count — noise around a steady value crosses its mean again and again (the
    constant horizontal velocity of a throw, the still coordinate of a fall) but is no oscillation. Resolved: √2·std
    of q_j at least RESOLVED_SNR·σ_j, and for q̇_j also the swing of position it implies, √2·std(q̇_j)·P_j/2π with
    P_j that column's own period. When no column is resolved (white noise; a cosine sampled below its Nyquist rate
    looks like noise to a noise estimate) all columns count, as without ``position_noise``."""
    x = np.asarray(x, float)
    x = x[:, None] if x.ndim == 1 else x
    t = np.asarray(t, float)
    k = x.shape[1]
    spans, gaps = np.zeros(k), np.zeros(k)
    sq, cnt = np.zeros(k), 0
    for s in segs:
        if len(s) < 3:
            continue
        ts = t[s]
        xs = x[s] - x[s].mean(axis=0)
        sq += np.sum(xs**2, axis=0)
        cnt += len(s)
        for j in range(k):
            y = xs[:, j]
            i = _crossings(y)
            if len(i) < 2:
                continue
            tc = ts[i] - y[i] * (ts[i + 1] - ts[i]) / (y[i + 1] - y[i])
            spans[j] += tc[-1] - tc[0]
            gaps[j] += len(tc) - 1
    if position_noise is not None and cnt:
        sig = np.asarray(position_noise, float)
        n = len(sig)
        if k != 2 * n:
            raise ValueError(f"position_noise needs x = [q, q̇] ({2 * n} columns), got {k}")
        amp = np.sqrt(2 * sq / cnt)
        per = np.where(gaps > 0, 2.0 * spans / np.maximum(gaps, 1), 0.0)
        amp[n:] *= per[n:] / (2 * np.pi)  # a velocity swing as the swing of position it implies
        ok = amp >= RESOLVED_SNR * np.concatenate([sig, sig])
        ok[n:] &= ok[:n]  # the velocity of positions that are all noise is noise too
        if ok.any():  # else every column is noise-like (white noise, a cosine sampled below Nyquist): count them all
            gaps = np.where(ok, gaps, 0.0)
    j = int(np.argmax(gaps))
    return 2.0 * spans[j] / gaps[j] if gaps[j] >= 2 else math.inf


def evidence_block(period: float, t, segs) -> float:
    """The time of one block of the record-level evidence: the period when the motion oscillates, else (a throw, a
    fall, a coast-down, an arc of an orbit: no period exists) 1/NONOSC_BLOCKS of the median trajectory's duration."""
    if np.isfinite(period) and period > 0:
        return float(period)
    t = np.asarray(t, float)
    spans = [float(t[s][-1] - t[s][0]) for s in segs if len(s) > 1]
    span = float(np.median(spans)) if spans else 0.0
    return span / NONOSC_BLOCKS if span > 0 else math.inf


def velocity_time_scale(qd, qdd, segs, columns=None) -> float:
    """The time over which the velocity changes by its own size: per coordinate rms(q̇)/rms(q̈) over the rows of
    ``segs``, the smallest over ``columns`` (default all; pass those whose q̈ is resolved above the noise). For
    q = A cos ωt it is 1/ω = period/2π, so 2π times it is the time scale of motion that does not oscillate.
    inf when no coordinate accelerates."""
    qd, qdd = np.atleast_2d(np.asarray(qd, float)), np.atleast_2d(np.asarray(qdd, float))
    rows = np.concatenate(list(segs)) if len(segs) else np.arange(len(qd))
    cols = range(qd.shape[1]) if columns is None else columns
    taus = []
    for j in cols:
        v = math.sqrt(float(np.mean(qd[rows, j] ** 2)))
        a = math.sqrt(float(np.mean(qdd[rows, j] ** 2)))
        if a > 0 and v > 0:
            taus.append(v / a)
    return min(taus) if taus else math.inf


def period_blocks(t, segs, period) -> list[list[np.ndarray]]:
    """Per segment, the row indices of consecutive whole blocks of duration ``period`` (last partial block dropped)."""
    t = np.asarray(t, float)
    out = []
    for s in segs:
        ts = t[s]
        if not np.isfinite(period) or period <= 0:
            out.append([])
            continue
        k = np.floor((ts - ts[0]) / period).astype(int)
        nfull = int(np.floor((ts[-1] - ts[0]) / period))
        out.append([s[k == i] for i in range(nfull) if np.sum(k == i) >= 2])
    return out


def _time_mean(y, t) -> float:
    if len(t) < 2 or t[-1] <= t[0]:
        return float(np.mean(y))
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)) / (t[-1] - t[0]))


# ------------------------------------------------------------------------------------------------------------------
# energy trend


def _trend_regression(ys, ts):
    """Common slope with one intercept per group: (slope, se, dof, residuals, lag-1 autocorrelation)."""
    y = []
    G = len(ys)
    X = []
    for g, (yy, tt) in enumerate(zip(ys, ts)):
        for a, b in zip(yy, tt):
            e = np.zeros(G + 1)
            e[g] = 1.0
            e[G] = b
            X.append(e)
            y.append(a)
    X, y = np.asarray(X), np.asarray(y)
    dof = len(y) - (G + 1)
    if dof < 1:
        return float("nan"), float("inf"), dof, np.zeros(0), 0.0
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - X @ coef
    s2 = float(res @ res) / dof
    cov = s2 * np.linalg.pinv(X.T @ X)
    se = math.sqrt(max(cov[G, G], 0.0))
    # lag-1 autocorrelation of the residuals within groups
    num = den = 0.0
    i = 0
    for yy in ys:
        r = res[i : i + len(yy)]
        i += len(yy)
        num += float(np.sum(r[1:] * r[:-1]))
        den += float(np.sum(r * r))
    rho1 = max(0.0, min(0.9, num / den)) if den > 0 else 0.0
    return float(coef[G]), se * math.sqrt((1 + rho1) / (1 - rho1)), dof, res, rho1


def _block_trend(V, floor: float, t, blocks, period: float, n_boot: int, seed: int) -> dict:
    """Trend of log(per-period mean of V − floor): rate (> 0: decay), se, z, blocks and bootstrap z's."""
    ys, ts, raw_t, raw_v = [], [], [], []
    ok = True
    for bl in blocks:
        if len(bl) < 2:
            continue
        m = np.array([_time_mean(V[b], t[b]) for b in bl]) - floor
        tt = np.array([float(np.mean(t[b])) for b in bl])
        if np.any(m <= 0) or not np.all(np.isfinite(m)):
            ok = False
            continue
        ys.append(np.log(m))
        ts.append(tt)
        raw_t.append(tt.tolist())
        raw_v.append(m.tolist())
    n_blocks = int(sum(len(y) for y in ys))
    out = {
        "rate": float("nan"),
        "se": float("inf"),
        "z": 0.0,
        "rate_per_period": float("nan"),
        "n_blocks": n_blocks,
        "period": float(period),
        "valid": False,
        "rho1": 0.0,
        "block_t": raw_t[:8],
        "block_dE": raw_v[:8],
        "bootstrap_z": [],
        "all_blocks_positive": ok,
    }
    if n_blocks < MIN_BLOCKS:
        out["reason"] = f"{n_blocks} whole periods (at least {MIN_BLOCKS} are needed)"
        return out
    slope, se, dof, _res, rho1 = _trend_regression(ys, ts)
    if not np.isfinite(slope) or dof < 2:
        out["reason"] = "too few periods per trajectory"
        return out
    rate = -slope
    z = rate / se if se > 0 else (math.inf if rate != 0 else 0.0)
    rng = np.random.default_rng(seed)
    zb = []
    for _ in range(n_boot):
        yb, tb = [], []
        for yy, tt in zip(ys, ts):
            idx = np.sort(rng.integers(0, len(yy), len(yy)))
            yb.append(yy[idx])
            tb.append(tt[idx])
        sb, seb, _, _, _ = _trend_regression(yb, tb)
        if np.isfinite(sb) and seb > 0 and np.isfinite(seb):
            zb.append(-sb / se)  # spread of the estimate in units of the original se
    out.update(
        rate=float(rate),
        se=float(se),
        z=float(z),
        rate_per_period=float(rate * period),
        valid=bool(ok),
        rho1=float(rho1),
        dof=int(dof),
        bootstrap_z=[float(v) for v in zb],
    )
    if not ok:
        out["reason"] = "the mean is at or below the floor in some period"
    return out


def percent_per_period(rate_per_period: float) -> float:
    """The energy lost (r·period > 0) or gained per period, in % of the energy at its start: E ∝ exp(−r t), so a
    decay is 100·(1 − e^(−r·period)) — never above 100 % (r·period = 2 is 86 %, not "200 %/period") — and a growth
    100·(e^(r·period) − 1); the magnitude. For small r·period both are ≈ 100·|r·period|."""
    x = float(rate_per_period)
    return 100.0 * (-np.expm1(-x) if x >= 0 else np.expm1(-x))


def energy_trend(E, E_floor: float, t, segs, period: float, n_boot: int = 200, seed: int = 0, kinetic=None) -> dict:
    """Relative energy-decay rate r of per-period means of E over whole trajectories, with its significance.

    E (N,) the learned energy at the rows; E_floor its minimum at rest; t (N,) times; segs: row indices per
    trajectory (sorted by t); period: the oscillation period (same time unit). Returns ``rate`` r (> 0: decay),
    ``se``, ``z`` = r/se, ``rate_per_period`` = r·period, ``n_blocks``, ``valid`` (≥ MIN_BLOCKS blocks and a positive
    energy above the floor in every block), per-block ``block_t`` / ``block_dE`` (mean energy above the floor;
    first 8 trajectories), ``rho1`` and ``bootstrap_z`` (z of the replicas of a block bootstrap within
    trajectories).

    ``kinetic`` (N,), optional: q̇ᵀ(∂²L/∂q̇²)q̇ at the rows. On oscillations its per-period mean follows the energy
    above the minimum (virial theorem: ⟨T⟩ = kE/(k+2) for V ∝ rᵏ, k > 0), so its trend cross-checks the learned
    energy: a learned Lagrangian whose energy does not grow with the size of the motion (a poor fit) shows a trend
    of the wrong sign. When both trends are significant (|z| ≥ 2) with opposite signs, the energy trend is marked
    invalid (``consistent`` False, with the reason) — not replaced by the kinetic one, whose relation to the
    energy flips sign for attractive potentials like 1/r (⟨T⟩ = −E). ``kinetic_rate``/``kinetic_z`` are reported.
    """
    E = np.asarray(E, float)
    t = np.asarray(t, float)
    blocks = period_blocks(t, segs, period)
    out = _block_trend(E, E_floor, t, blocks, period, n_boot, seed)
    out["consistent"] = True
    if kinetic is None:
        return out
    kin = _block_trend(np.asarray(kinetic, float), 0.0, t, blocks, period, n_boot, seed + 1)
    out.update(kinetic_rate=kin["rate"], kinetic_se=kin["se"], kinetic_z=kin["z"])
    if (
        kin["valid"]
        and out["valid"]
        and abs(kin["z"]) >= 2
        and abs(out["z"]) >= 2
        and np.sign(kin["z"]) != np.sign(out["z"])
    ):
        out.update(
            valid=False,
            consistent=False,
            reason=f"the learned energy trends the other way (z = {out['z']:.1f}) from the kinetic energy "
            f"(z = {kin['z']:.1f}): either the learned Lagrangian is not a usable energy, or the "
            "potential is attractive like 1/r (there ⟨T⟩ = −E); the energy trend is not used",
        )
    return out


def _moving_average(y: np.ndarray, w: int) -> np.ndarray:
    if w <= 1 or len(y) < w:
        return y
    c = np.cumsum(np.concatenate([[0.0], y]))
    m = (c[w:] - c[:-w]) / w
    pad = (len(y) - len(m)) // 2
    return np.concatenate([np.full(pad, m[0]), m, np.full(len(y) - len(m) - pad, m[-1])])


def fit_error_bound(E, power, t, segs, period: float, floor: float) -> dict:
    """How far the learned Lagrangian's own fit error could move its energy along the record — the bound a trend of
    the learned energy must clear (:func:`nnphd.user.checks.within_fit_error`).

    The learned energy H changes along the data at exactly the power P = q̇ᵀ(∂²L/∂q̇²) r of the residual
    r = q̈ − f_c. Where the motion is conservative, r is the Lagrangian's approximation error (and the q̈ noise): its
    power moves energy in and out within each period, and on a record whose orbit drifts through its states
    (precession, a rotating frame, a quasi-periodic orbit) the per-period means of H can drift by about as much as
    one period moves — a trend at any z. Per block of one period (relative to the block's mean energy above the
    floor): ``gross_smooth`` = ∫|P̄| dt with P averaged over an eighth of a period (the q̈ noise averaged down), the
    median over blocks; ``periods``: whole blocks in the median trajectory."""
    E, power, t = (np.asarray(a, float) for a in (E, power, t))
    per_traj = period_blocks(t, segs, period)
    blocks = [b for bl in per_traj for b in bl if len(b) >= 4]
    if not blocks:
        return {"fit_error": None}
    gross_s = []
    for b in blocks:
        tb, pb, eb = t[b], power[b], E[b]
        scale = max(_time_mean(eb, tb) - floor, 1e-300)
        gross_s.append(_time_mean(np.abs(_moving_average(pb, max(1, len(b) // 8))), tb) * (tb[-1] - tb[0]) / scale)
    return {
        "fit_error": {
            "gross_smooth": float(np.median(gross_s)),
            "n_blocks": len(blocks),
            "periods": float(np.median([len(bl) for bl in per_traj])),
        }
    }


# ------------------------------------------------------------------------------------------------------------------
# multiple shooting
