r"""The amplitude envelope of a damped oscillation — the picture physicists use to tell friction laws apart — measured
from the record (:func:`measured_envelope`) and predicted by a candidate law (:func:`predicted_envelope`).

Measured: the half swings between successive turning points (where the estimated velocity changes sign), each at
the midpoint time — a turning point's time is where the velocity crosses zero, interpolated between the two rows
around the sign change (the row after it sets the time only to within a sample: at 66 Hz 3.6 % of a half period,
more than a 0.5-rad pendulum's 1.4 % lengthening, which is how its orbit is told from a harmonic one); swings below
:data:`MIN_SWING_SIGMA`·σ (noise, a body at rest) are dropped.

Predicted (one coordinate, energy balance over one cycle of the harmonic motion q = q₀ + A cos φ, q̇ = −Aω sin φ):

    dA/dt = ⟨g(q, q̇, t)·q̇⟩_φ / (ω² A),

so viscous −γq̇ gives A' = −γA/2 (exponential: a straight line on a log axis), dry −μ sign(q̇) gives A' = −2μ/(πω)
(linear: the log curve bends down), quadratic −c|q̇|q̇ gives A' = −(4/3π) c ω A² (≈ 1/(1 + βt): the log curve bends
up), mixed laws the sums. Integrated from the first measured amplitude (RK4 on the measured times); it stops at
A = 0 (dry friction ends the motion in finite time); a law that cannot be integrated leaves NaN from there on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from nnphd.explain.trajectory import Motion

__all__ = ["envelope_evidence", "fit_envelope", "measured_envelope", "predicted_envelope", "swing_orbit"]

MIN_SWING_SIGMA = 6.0
N_PHASE = 64  # points of the cycle average
MAX_PENDULUM_SWING = 3.0  # rad: half swings of a pendulum beyond this (near the top, whole turns) are not averaged


@dataclass(frozen=True)
class Orbit:
    """The conservative motion a cycle average runs over: harmonic, q = q0 + A cos(ωt), or (``pendulum``) the exact
    orbit of q̈ = −ω² sin(q − q0), sin((q − q0)/2) = k sn(ωt, k), q̇ = 2kω cn(ωt, k), k = sin(A/2) — at 157° a
    pendulum's speed profile is far from a sine, and its energy per amplitude is ω² sin A, not ω² A."""

    omega: float
    q0: float = 0.0
    pendulum: bool = False

    def states(self, A) -> tuple[np.ndarray, np.ndarray]:
        """(q, q̇), each (len(A), N_PHASE): one cycle at each amplitude, sampled uniformly in time."""
        from scipy.special import ellipj, ellipk

        A = np.asarray(A, float)[:, None]
        s = (np.arange(N_PHASE) + 0.5) / N_PHASE
        if not self.pendulum:
            phi = 2 * np.pi * s
            return self.q0 + A * np.cos(phi), -A * self.omega * np.sin(phi)
        k = np.sin(np.minimum(A, MAX_PENDULUM_SWING) / 2)
        m = k**2
        sn, cn, _, _ = ellipj(4 * ellipk(m) * s, m)
        return self.q0 + 2 * np.arcsin(k * sn), 2 * k * self.omega * cn

    def energy_slope(self, A) -> np.ndarray:
        """dE/dA per unit mass: the restoring force at the turning point."""
        A = np.asarray(A, float)
        return self.omega**2 * (np.sin(np.minimum(A, MAX_PENDULUM_SWING)) if self.pendulum else A)

    def half_period(self, A) -> np.ndarray:
        from scipy.special import ellipk

        A = np.asarray(A, float)
        if not self.pendulum:
            return np.full(A.shape, np.pi / self.omega)
        return 2 * ellipk(np.sin(np.minimum(A, MAX_PENDULUM_SWING) / 2) ** 2) / self.omega


def measured_envelope(q, qd, t, traj, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_mid, A, trajectory id) of the half swings of one coordinate q (N,) with velocity qd (N,)."""
    q, qd, t, traj = (np.asarray(a) for a in (q, qd, t, traj))
    out_t, out_a, out_k = [], [], []
    cuts = np.flatnonzero(np.diff(traj) != 0) + 1
    for seg in np.split(np.arange(len(t)), cuts):
        s = np.sign(qd[seg])
        turn = np.flatnonzero((s[1:] * s[:-1]) < 0) + 1  # the first row after each sign change
        r = seg[turn]
        frac = qd[r - 1] / (qd[r - 1] - qd[r])  # in (0, 1): the two velocities have opposite signs
        t_turn = t[r - 1] + frac * (t[r] - t[r - 1])  # the velocity's zero crossing, interpolated
        for n, (a, b) in enumerate(zip(turn[:-1], turn[1:])):
            i, j = seg[a], seg[b]
            swing = abs(q[j] - q[i])
            if swing >= MIN_SWING_SIGMA * sigma:
                out_t.append(0.5 * (t_turn[n] + t_turn[n + 1]))
                out_a.append(0.5 * swing)
                out_k.append(traj[i])
    return np.asarray(out_t, float), np.asarray(out_a, float), np.asarray(out_k)


def _rate(law, A: float, orbit: Orbit, t: float) -> float:
    """dA/dt of the cycle-averaged energy balance at amplitude A."""
    if A <= 0:
        return 0.0
    q, v = (x[0] for x in orbit.states([A]))
    with np.errstate(all="ignore"):  # a candidate's law may overflow at a trial amplitude: that rate is NaN
        g = np.asarray(law(q[:, None], v[:, None], np.full(N_PHASE, t)), float)[:, 0]
        return float(np.mean(g * v) / orbit.energy_slope(A))


def predicted_envelope(law, t, A0: float, q0: float, omega: float, orbit: Orbit | None = None) -> np.ndarray:
    """A(t) at the times t (increasing; t[0] the start, A(t[0]) = A0) under ``law(q, qd, t)`` → (N, 1) (one
    coordinate), oscillating at angular frequency omega about q0 (or on ``orbit``); RK4 with ≥ 20 steps per
    interval of t, no negative amplitude."""
    orbit = orbit or Orbit(omega, q0)
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
            k1 = _rate(law, a, orbit, tt)
            k2 = _rate(law, max(a + 0.5 * h * k1, 0.0), orbit, tt + 0.5 * h)
            k3 = _rate(law, max(a + 0.5 * h * k2, 0.0), orbit, tt + 0.5 * h)
            k4 = _rate(law, max(a + h * k3, 0.0), orbit, tt + h)
            a = max(a + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), 0.0)
            if not np.isfinite(a):
                A[k:] = np.nan  # the law cannot be integrated from here: no envelope
                return A
            tt += h
        A[k] = a
    return A


PICTURE_GRID = 512  # amplitudes of the tabulated rate of the report's predicted envelopes (10⁻³·min A … 2·max A)


def tabulated_rate(law, grid, orbit: Orbit, times: tuple[float, float]) -> np.ndarray | None:
    """The cycle-averaged dA/dt of ``law(q, qd, t)`` at the amplitudes ``grid`` (one vectorised call), or None when
    the law depends on time (it differs at the record's first and last ``times``: a drive) or overflows — then the
    envelope is integrated step by step (:func:`predicted_envelope`). A record of 900 half swings took 44 s to draw
    four candidates' envelopes by RK4 steps (284 160 cycle averages); the table takes one call per candidate, and
    :func:`envelope_curve` inverts it as the envelope evidence does."""
    qs, vs = orbit.states(grid)
    q, v = qs.reshape(-1, 1), vs.reshape(-1, 1)
    with np.errstate(all="ignore"):
        g = [np.asarray(law(q, v, np.full(len(q), t)), float)[:, 0] for t in times]
        if not np.array_equal(g[0], g[1]):
            return None
        R = (g[0] * v[:, 0]).reshape(len(grid), N_PHASE).mean(axis=1) / orbit.energy_slope(grid)
    return R if np.all(np.isfinite(R)) else None


def envelope_report(
    rows, motion: Motion, sigma: float, period: float, limit: int = 4, angle: bool = False
) -> dict | None:
    """The measured envelope of the first coordinate of ``motion`` (its trajectory ids given; ``sigma`` its position
    noise) and the envelope each of the first ``limit`` candidate laws of ``rows`` (Candidate, best first; the zero
    law skipped) predicts, per trajectory from its first measured amplitude; with each one's rms log-error against
    the measured amplitudes (JSON-ready). None without ≥ 4 half swings or a finite period."""
    if not np.isfinite(period) or period <= 0:
        return None
    q, qd = np.asarray(motion.q)[:, 0], np.asarray(motion.qd)[:, 0]
    q, qd, t, traj = (np.asarray(a) for a in (q, qd, motion.t, motion.traj))
    tm, A, k = measured_envelope(q, qd, t, traj, sigma)
    if len(A) < 4:
        return None
    q0 = swing_centre(q, qd, traj)
    orbit = swing_orbit(tm, A, k, q0, angle) or Orbit(2 * np.pi / period, q0)
    omega = orbit.omega
    out = {
        "measured": {"t": tm.tolist(), "A": A.tolist(), "traj": [int(x) for x in k]},
        "omega": omega,
        "q0": q0,
        "orbit": "pendulum" if orbit.pendulum else "harmonic",
        "candidates": [],
    }
    top = 2.0 * A.max() if not orbit.pendulum else min(2.0 * A.max(), MAX_PENDULUM_SWING)
    grid = np.geomspace(1e-3 * A.min(), max(top, 1.01 * A.max()), PICTURE_GRID)
    for r in [r for r in rows if r.family is not None][:limit]:
        law = lambda a, b, c, r=r: r.predict(a, b, c)  # noqa: E731
        rate = tabulated_rate(law, grid, orbit, (float(tm.min()), float(tm.max())))
        pred = np.empty_like(A)
        for kk in np.unique(k):
            m = k == kk
            if rate is not None:
                pred[m] = envelope_curve(rate, grid, float(A[m][0]), tm[m] - tm[m][0])
            else:
                pred[m] = predicted_envelope(law, tm[m], A[m][0], q0, omega, orbit)
        ok = np.isfinite(pred) & (pred > 0)
        err = float(np.sqrt(np.mean(np.log(pred[ok] / A[ok]) ** 2))) if ok.sum() >= 2 else float("nan")
        out["candidates"].append({"law": r.key, "title": r.title, "A": pred.tolist(), "rms_log_error": err})
    return out


# ---- the envelope as evidence: each candidate family fitted to the measured envelope ------------------------------
ENV_GRID = 256  # amplitudes of the tabulated cycle-averaged rates
ENV_FLOOR = 0.01  # relative error of a measured half swing beyond the position noise (anharmonicity, asymmetry)
ORBIT_TOL = 0.06  # the orbit's half periods off the measured ones by more (median): the envelope is not evidence
# (measured: a double well 0.10 — its envelope coefficients contradict the windows —, a 10 Hz seismometer 0.04)
MIN_ENV_SWINGS = 6  # fewer half swings: the envelope is shown, not used as evidence
# a constant amplitude (the zero law) fits the measured envelope to this χ²/N or better: the amplitudes do not change
# (a limit cycle, a steady drive), the envelope pins at most one combination of the coefficients — the amplitude
# where gain and loss balance — and its check abstains instead of vetoing (measured: a Rayleigh oscillator on its
# limit cycle, whose windows pinned a = 0.2002 ± 0.0002, c = −0.2002 ± 0.0002, lost its law to a "disagreement"
# of Mahalanobis² 39 with an envelope that could not inform; tests/test_envelope_evidence.py)
FLAT_ENVELOPE_CHI2 = 2.0
AGREE_P = 0.997  # the windows' and the envelope's coefficients differ beyond this quantile of χ²(K): two laws
TIME_FAMILIES = ("drive",)  # a cycle average of the motion loses a drive's phase: not fitted to the envelope


def swing_centre(q, qd, traj) -> float:
    """The median centre of the half swings (the rest angle of the oscillation)."""
    q, qd, traj = (np.asarray(a) for a in (q, qd, traj))
    centres = []
    cuts = np.flatnonzero(np.diff(traj) != 0) + 1
    for seg in np.split(np.arange(len(q)), cuts):
        s = np.sign(qd[seg])
        turn = seg[np.flatnonzero((s[1:] * s[:-1]) < 0) + 1]
        centres += [0.5 * (q[i] + q[j]) for i, j in zip(turn[:-1], turn[1:])]
    return float(np.median(centres)) if centres else float(np.median(q))


def _rate_columns(fam, theta, grid, orbit: Orbit) -> np.ndarray | None:
    """(len(grid), K [+1]) the cycle-averaged dA/dt of each of the family's terms at the amplitudes ``grid`` (its
    parameter-free part, if any, last); None where a term overflows."""
    qs, vs = orbit.states(grid)
    q, v = qs.reshape(-1, 1), vs.reshape(-1, 1)
    t = np.zeros(len(q))
    with np.errstate(all="ignore"):
        B = np.asarray(fam.basis(np, np.asarray(theta, float), q, v, t), float)[:, 0, :]
        if fam.fixed is not None:
            B = np.concatenate([B, np.asarray(fam.fixed(np, theta, q, v, t), float)[:, :1]], axis=1)
        R = (B * v).reshape(len(grid), N_PHASE, -1).mean(axis=1) / orbit.energy_slope(grid)[:, None]
    return R if np.all(np.isfinite(R)) else None


def swing_orbit(tm, A, k, q0: float, angle: bool) -> Orbit | None:
    """The orbit of the cycle averages, from the measured half swings: ω from the times between successive ones;
    for an angle, the pendulum's orbit when its amplitude-dependent half period fits them better than a constant
    one (a torsion oscillator read as an angle stays harmonic). None with fewer than two half swings."""
    from scipy.special import ellipk

    tm, A, k = (np.asarray(x) for x in (tm, A, k))
    dt, amp = [], []
    for kk in np.unique(k):
        m = k == kk
        dt.append(np.diff(tm[m]))
        amp.append(0.5 * (A[m][1:] + A[m][:-1]))
    dt, amp = np.concatenate(dt or [np.zeros(0)]), np.concatenate(amp or [np.zeros(0)])
    ok = dt > 0
    if not ok.any():
        return None
    dt, amp = dt[ok], amp[ok]
    harmonic = Orbit(float(np.pi / np.median(dt)), q0)
    if not angle:
        return harmonic
    K2 = 2 * ellipk(np.sin(np.minimum(amp, MAX_PENDULUM_SWING) / 2) ** 2)
    pend = Orbit(float(np.median(K2 / dt)), q0, pendulum=True)
    err = [float(np.median(np.abs(o.half_period(amp) / dt - 1))) for o in (harmonic, pend)]
    return pend if err[1] < err[0] else harmonic


def orbit_misfit(orbit: Orbit, tm, A, k) -> float:
    """The median relative error of the orbit's half period against the measured ones: a motion whose half period
    depends on its swing in a way the orbit does not (a double well, a stiffening spring) is no cycle of it."""
    tm, A, k = (np.asarray(x) for x in (tm, A, k))
    errs = []
    for kk in np.unique(k):
        m = k == kk
        dt = np.diff(tm[m])
        amp = 0.5 * (A[m][1:] + A[m][:-1])
        ok = dt > 0
        errs.append(np.abs(orbit.half_period(amp[ok]) / dt[ok] - 1))
    e = np.concatenate(errs or [np.zeros(0)])
    return float(np.median(e)) if e.size else float("inf")


def envelope_curve(rate: np.ndarray, grid: np.ndarray, A0: float, dt: np.ndarray) -> np.ndarray:
    """A at the times dt ≥ 0 after A(0) = A0 under the autonomous dA/dt = rate(A), tabulated on the increasing
    ``grid``: the time to go from A0 to a is ∫ da/rate, so A(t) follows by inverting a cumulative quadrature — down
    the grid where the rate at A0 is negative (decay), up it where positive (growth); where the rate changes sign
    the envelope stalls there (a limit cycle), and at the grid's end it stays."""
    r0 = float(np.interp(A0, grid, rate))
    if r0 == 0 or not np.isfinite(r0):
        return np.full(len(dt), A0)
    down = r0 < 0
    g = grid[grid < A0][::-1] if down else grid[grid > A0]
    gg = np.concatenate([[A0], g])
    rr = np.concatenate([[r0], np.interp(g, grid, rate)])
    same = rr < 0 if down else rr > 0
    stop = int(np.argmin(same)) if not same.all() else len(rr)  # the first grid point where the motion stalls
    gg, rr = gg[:stop], rr[:stop]
    if len(gg) < 2:
        return np.full(len(dt), A0)
    with np.errstate(over="ignore", divide="ignore"):  # a rate of ~1e-308: an infinite crossing time, a stall
        seg = 0.5 * (1 / rr[1:] + 1 / rr[:-1]) * np.diff(gg)  # time to cross each grid interval (> 0)
    tau = np.concatenate([[0.0], np.cumsum(seg)])
    return np.interp(dt, tau, gg)


def fit_envelope(rows, tm, A, k, sigma: float, orbit: Orbit) -> list[dict]:
    """Each candidate family of ``rows`` (Candidate; the zero law included; drives skipped) fitted to the measured
    envelope (tm, A, k) of :func:`measured_envelope`: its coefficients β (nonlinear parameters held at the row's
    values) and each trajectory's starting amplitude, by least squares on log A weighted by the half swing's error
    (σ/√2 position noise, and :data:`ENV_FLOOR`), started from the row's own β. Returns one dict per row fitted:
    key, row, beta, cov (β's covariance, unscaled: (JᵀJ)⁻¹), chi2, k (parameters), resid (weighted residuals)."""
    from scipy.optimize import least_squares

    tm, A, k = (np.asarray(x) for x in (tm, A, k))
    w = 1.0 / np.sqrt((sigma / np.sqrt(2) / A) ** 2 + ENV_FLOOR**2)
    logA = np.log(A)
    trajs = np.unique(k)
    top = 2.0 * A.max() if not orbit.pendulum else min(2.0 * A.max(), MAX_PENDULUM_SWING)
    grid = np.geomspace(0.25 * A.min(), max(top, 1.01 * A.max()), ENV_GRID)
    a0 = np.array([logA[k == kk][0] for kk in trajs])
    out = []
    for r in rows:
        fam = r.family
        if fam is not None and any(s in r.key for s in TIME_FAMILIES):
            continue
        cols = np.zeros((ENV_GRID, 0)) if fam is None else _rate_columns(fam, r.theta, grid, orbit)
        if cols is None:
            continue
        nb = 0 if fam is None else len(r.beta)
        fixed = np.ones(cols.shape[1] - nb)  # a user law's parameter-free part enters as is

        def resid(p, cols=cols, nb=nb, fixed=fixed):
            rate = cols @ np.concatenate([p[:nb], fixed]) if cols.shape[1] else np.zeros(ENV_GRID)
            res = np.empty(len(A))
            for j, kk in enumerate(trajs):
                m = k == kk
                curve = envelope_curve(rate, grid, float(np.exp(p[nb + j])), tm[m] - tm[m][0])
                res[m] = (np.log(np.maximum(curve, 1e-300)) - logA[m]) * w[m]
            return res

        p0 = np.concatenate([np.asarray(r.beta, float)[:nb] if nb else np.zeros(0), a0])
        try:
            fit = least_squares(resid, p0, x_scale="jac", max_nfev=100 * len(p0))
        except ValueError:
            continue
        res = resid(fit.x)
        if not np.all(np.isfinite(res)):
            continue
        J = fit.jac
        cov = np.linalg.pinv(J.T @ J)[:nb, :nb]
        out.append(
            {
                "key": r.key,
                "row": r,
                "beta": fit.x[:nb],
                "cov": cov,
                "chi2": float(res @ res),
                "k": len(p0),
                "resid": res,
            }
        )
    return out


def envelope_evidence(table, q, qd, t, traj, sigma: float, angle: bool = False):
    """The law table re-ranked with the amplitude envelope as a second, independent piece of evidence (one
    coordinate, ≥ :data:`MIN_ENV_SWINGS` half swings; else the table as it is).

    The trajectory-level windows start from free states: they see how the force acts *within* a window, not how
    the energy falls *between* windows — the amplitude dependence of the loss that tells viscous (exponential), dry
    (linear) and quadratic (~1/(1+βt)) friction apart over a long record, and that a jittered clock does not blur.
    Each family is fitted to the measured envelope (:func:`fit_envelope`, on the orbit of :func:`swing_orbit`); its
    envelope IC, n_eff·log(χ²/n) + k·log(n_eff) (n_eff = n/τ, τ from the lag-1 correlation of the best fit's
    residuals), relative to the zero law's, is added to its windows' IC, and its coefficients are pooled from the
    two fits (:func:`pooled_row`: eligible only where they agree — a Rayleigh law that pumps energy into a decaying
    record in the windows and damps it in the envelope is not one law). The envelope sorts the families the windows
    do not reject (windows' ΔIC < IC_TIE); it never makes a law on its own. Drives are not fitted to the envelope
    (a cycle average loses their phase): they keep their windows' IC."""
    from dataclasses import replace

    from nnphd.explain.table import IC_TIE, select_law

    q, qd, t, traj = (np.asarray(a) for a in (q, qd, t, traj))
    tm, A, k = measured_envelope(q, qd, t, traj, sigma)
    if angle:  # near the top a pendulum's swing is no oscillation about q0
        keep = A <= MAX_PENDULUM_SWING
        tm, A, k = tm[keep], A[keep], k[keep]
    orbit = swing_orbit(tm, A, k, swing_centre(q, qd, traj), angle)
    if len(A) < MIN_ENV_SWINGS or orbit is None or orbit_misfit(orbit, tm, A, k) > ORBIT_TOL:
        return table
    fits = fit_envelope(table.rows, tm, A, k, sigma, orbit)
    zero = next((f for f in fits if f["key"] == "none"), None)
    if zero is None or len(fits) < 2:
        return table
    n = len(A)
    if zero["chi2"] / n <= FLAT_ENVELOPE_CHI2:  # the amplitudes do not change: the envelope cannot inform
        why = (
            f"the amplitude envelope abstains: a constant amplitude fits its {n} half swings to their errors "
            f"(χ²/N = {zero['chi2'] / n:.2f} ≤ {FLAT_ENVELOPE_CHI2:g}), as on a limit cycle — it carries no "
            "evidence on how the loss depends on the amplitude, so the windows decide"
        )
        return replace(table, settings={**table.settings, "envelope_abstains": why})
    best = min(fits, key=lambda f: f["chi2"])
    res = best["resid"]
    rho = float(np.clip(np.sum(res[1:] * res[:-1]) / max(np.sum(res * res), 1e-300), 0.0, 0.95))
    n_eff = n / ((1 + rho) / (1 - rho))

    def ic(f):
        return n_eff * np.log(max(f["chi2"], 1e-300) / n) + f["k"] * np.log(max(n_eff, 2.0))

    by_row = {id(f["row"]): f for f in fits}
    rows = []
    for r in table.rows:
        f = by_row.get(id(r))
        if f is None or r.family is None:
            rows.append(replace(r, significant=r.significant if r.family is not None else True))
            continue
        d_ic = float(ic(f) - ic(zero))
        new = pooled_row(r, f, n, n_eff, q, qd, t, table.settings["names"])
        new.ic, new.delta_ic = r.ic + d_ic, r.delta_ic + d_ic
        new.heldout_mse, new.heldout_ratio = r.heldout_mse, r.heldout_ratio
        new.envelope["delta_ic"] = d_ic
        new.envelope["windows"] = {"params": dict(r.params), "stderr": dict(r.stderr), "delta_ic": r.delta_ic}
        # the envelope sorts the families the windows do not reject: it does not make a law they reject
        new.significant = bool(new.significant and r.delta_ic < IC_TIE)
        rows.append(new)
    out = select_law(
        rows,
        table.n_eff,
        table.tau,
        table.folds + f" + the amplitude envelope ({n} half swings)",
        {**table.settings, "envelope_swings": n, "envelope_omega": orbit.omega, "envelope_pendulum": orbit.pendulum},
        judge=False,
        base=table.base,
    )
    blocked = blocked_by_disagreement(out)
    if blocked is not None:
        out.law, out.ties = None, []
        zero = [r for r in out.rows if r.key == "none"]
        out.rows = [*zero, blocked, *(r for r in out.rows if r is not blocked and r.key != "none")]
        out.blocked = blocked
        out.reason = (
            f"no law is claimed: the amplitude envelope clearly prefers {blocked.title} (envelope ΔIC "
            f"{blocked.envelope['delta_ic']:.1f} against no law, {IC_TIE:g} or more ahead of the best eligible "
            f"candidate's) and its windows do not reject it, but its windows and envelope disagree on its "
            f"coefficients (Mahalanobis distance² {blocked.envelope['distance2']:.1f}) — they are not pinned down, "
            "and a family the envelope rejects is no answer"
        )
        return out
    if out.law is not None:
        w = out.law.envelope or {}
        out.reason += (
            f"; with the amplitude envelope ({n} half swings{', a pendulum' if orbit.pendulum else ''}): "
            f"ΔIC {w.get('delta_ic', 0.0):.1f} from the envelope, {w.get('windows', {}).get('delta_ic', out.law.delta_ic):.1f} "
            "from the windows, the coefficients pooled from both fits"
        )
    return out


def blocked_by_disagreement(table):
    """The row that bars the table's law, or None: a candidate that fails eligibility only because its windows' and
    envelope's coefficients disagree, whose envelope fit is ≥ IC_TIE better than the law's (or no law's) and whose
    windows fit is no worse. The envelope is the evidence of how the loss depends on the amplitude: where it clearly
    prefers a description the windows do not reject, claiming a family it rejects is a confident answer the evidence
    does not give (a 157° encoder pendulum: viscous + dry friction, envelope ΔIC −65 against van der Pol's −31, its
    two fits 3.4 se apart — and van der Pol was claimed, 69 % off). A candidate only the windows prefer bars nothing
    (a seismometer's Rayleigh law, pumping energy in its windows, damping in its envelope: distance² 131)."""
    from nnphd.explain.table import IC_TIE

    ref = table.law if table.law is not None else next((r for r in table.rows if r.key == "none"), None)
    if ref is None:
        return None
    if ref.family is None:
        ref_env = ref_win = 0.0
    elif ref.envelope and "delta_ic" in ref.envelope:
        ref_env, ref_win = ref.envelope["delta_ic"], ref.envelope["windows"]["delta_ic"]
    else:  # a law not fitted to the envelope (a drive): nothing to compare
        return None

    def bars(r) -> bool:
        e = r.envelope or {}
        if r.family is None or r.significant or not e.get("eligible_but_agreement") or "delta_ic" not in e:
            return False
        return e["delta_ic"] <= ref_env - IC_TIE and e["windows"]["delta_ic"] <= ref_win

    bar = [r for r in table.rows if bars(r)]
    return min(bar, key=lambda r: r.ic) if bar else None


def pooled_row(r, f: dict, n: int, n_eff: float, q, qd, t, names):
    """The row with each coefficient pooled from its two independent estimates — the windows' (the table's) and
    the envelope's — by their inverse variances; eligible when the two agree (their Mahalanobis distance within the
    :data:`AGREE_P` quantile of χ²(K): else they are two different laws), each pooled term is ≥ Z_TERM se from zero and (a sum) carries ≥
    MIN_TERM_SHARE of the force, a sum of friction terms dissipates, and the table's other conditions hold."""
    from scipy.stats import chi2

    from nnphd.explain.table import MIN_TERM_SHARE, Z_TERM, dissipative_ok, law_row

    fam = r.family
    K = len(fam.coef_names)
    dof = max(n - f["k"], 1)
    C_env = np.asarray(f["cov"], float) * f["chi2"] / dof * n / n_eff
    se_tab = np.array([r.stderr.get(p, np.inf) for p in fam.coef_names], float)
    if r.cov is not None and np.all(np.isfinite(r.cov)):
        C_tab = np.asarray(r.cov, float)
    else:
        C_tab = np.diag(np.where(np.isfinite(se_tab) & (se_tab > 0), se_tab, 1e150) ** 2)
    b_tab, b_env = np.asarray(r.beta, float), np.asarray(f["beta"], float)
    Pt, Pe = np.linalg.pinv(C_tab), np.linalg.pinv(C_env)
    C = np.linalg.pinv(Pt + Pe)
    pooled = C @ (Pt @ b_tab + Pe @ b_env)
    se = np.sqrt(np.maximum(np.diag(C), 0.0))
    diff = b_tab - b_env
    d2 = float(diff @ np.linalg.pinv(C_tab + C_env) @ diff)  # Mahalanobis: the terms' trade-offs included
    agree = bool(d2 <= chi2.ppf(AGREE_P, K))
    se_nl = [r.stderr.get(p, np.nan) for p in fam.nl_names]
    new = law_row(fam, pooled, r.theta, np.concatenate([se, se_nl]), names, r.heldout_mse, r.method)
    new.on_rows(np.reshape(q, (-1, 1)), np.reshape(qd, (-1, 1)), t)
    new.fn_rel, new.cov = r.fn_rel, C
    ok = not fam.per_term or bool(np.all(np.abs(pooled) >= Z_TERM * se))
    if len(pooled) > 1 and fam.per_term:
        ok = ok and min(new.shares.values(), default=1.0) >= MIN_TERM_SHARE
    but_agree = bool(ok and dissipative_ok(fam, pooled) and _other_conditions(r))
    new.significant = but_agree and agree
    new.envelope = {
        "params": {p: float(x) for p, x in zip(fam.coef_names, b_env)},
        "stderr": {p: float(x) for p, x in zip(fam.coef_names, np.sqrt(np.maximum(np.diag(C_env), 0.0)))},
        "agree": agree,
        "distance2": d2,
        "eligible_but_agreement": but_agree,  # every other condition holds: only the two fits' disagreement bars it
    }
    return new


def _other_conditions(r) -> bool:
    """The table's conditions on a row other than its terms' size against their errors: not a drive locked to the
    motion, no parameter at the edge of its range, not at the rounding level of the data."""
    from nnphd.explain.table import DRIVE_STATE_R2, at_bound

    return r.state_like < DRIVE_STATE_R2 and r.fn_rel >= 1e-9 and not at_bound(r.family, r.theta)
