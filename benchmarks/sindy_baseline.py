"""SINDy peer baseline of issue 11: a plain PySINDy fit of the *whole* q̈, with the law read off afterwards.

Each trajectory's positions are differentiated with a Savitzky–Golay filter (``scipy.signal.savgol_filter``,
polyorder 4, window 15 samples or the largest odd number ≤ len/3, ``delta`` = the trajectory's median dt; the half
window at each end is dropped). All components of q̈ are then regressed with ``STLSQ`` on a cubic
``PolynomialLibrary`` of (q, q̇). The "law" is the part made of the monomials of odd total degree in the
velocities (x_dot, x^2*x_dot, x_dot^3, x_dot*y_dot^2, ...); the rest is taken as the conservative part.

Threshold rule: the library columns are scaled to unit rms and each q̈ component to unit rms, so the STLSQ threshold
is dimensionless (a raw coefficient c_j survives when |c_j|·rms(θ_j)/rms(q̈_k) ≥ threshold). With ``threshold=None``
each component picks its own threshold from the grid ``THRESHOLDS`` by minimising
BIC = m·log(RSS/m) + k·log(m) (m rows, k nonzero terms); a given ``threshold`` is used as is for every component.

Run the demo:  .venv/bin/python benchmarks/sindy_baseline.py
"""

from __future__ import annotations

import time

import numpy as np
import pysindy as ps
import sympy as sp
from scipy.signal import savgol_filter

THRESHOLDS = np.geomspace(1e-3, 0.5, 28)  # dimensionless STLSQ thresholds swept by the BIC rule
POLYORDER, WINDOW = 4, 15


def _sg_derivatives(t, q, traj):
    """Savitzky–Golay q, q̇, q̈ per trajectory, half window trimmed at both ends."""
    ids = np.zeros(len(t), int) if traj is None else np.asarray(traj)
    cuts = np.flatnonzero(np.diff(ids) != 0) + 1
    out = []
    for seg in np.split(np.arange(len(t)), cuts):
        w = min(WINDOW, (len(seg) // 3) - (1 - (len(seg) // 3) % 2))
        if w <= POLYORDER:
            raise ValueError(f"trajectory of {len(seg)} samples is too short for Savitzky–Golay")
        dt = float(np.median(np.diff(t[seg])))
        d = [savgol_filter(q[seg], w, POLYORDER, deriv=k, delta=dt, axis=0) for k in (0, 1, 2)]
        h = w // 2
        out.append([a[h : len(seg) - h] for a in d])
    return [np.concatenate(parts) for parts in zip(*out)]


def _stlsq(theta, y, threshold):
    opt = ps.STLSQ(threshold=threshold, alpha=1e-6, unbias=True)
    opt.fit(theta, y[:, None])
    return np.asarray(opt.coef_)[0]


def sindy_law(
    t: np.ndarray, q: np.ndarray, traj: np.ndarray | None, names: list[str], threshold: float | None = None
) -> dict:
    """Fit q̈ = Θ(q, q̇)·ξ with a cubic library and return its velocity-odd part (the law) -- see module docstring."""
    t0 = time.perf_counter()
    t, q = np.asarray(t, float), np.asarray(q, float).reshape(len(t), -1)
    n = q.shape[1]
    qs, qd, qdd = _sg_derivatives(t, q, traj)
    lib = ps.PolynomialLibrary(degree=3)
    theta = np.asarray(lib.fit_transform(np.hstack([qs, qd])))
    powers = np.asarray(lib.powers_)
    scale = np.sqrt(np.mean(theta**2, axis=0))
    scale[scale == 0] = 1.0
    ths, m = theta / scale, len(theta)
    coef, chosen = np.zeros((n, theta.shape[1])), []
    for k in range(n):
        ys = np.sqrt(np.mean(qdd[:, k] ** 2)) or 1.0
        best = None
        for thr in [threshold] if threshold is not None else THRESHOLDS:
            xi = _stlsq(ths, qdd[:, k] / ys, thr)
            rss = float(np.sum((ths @ xi - qdd[:, k] / ys) ** 2))
            bic = m * np.log(max(rss, 1e-300) / m) + np.count_nonzero(xi) * np.log(m)
            if best is None or bic < best[0]:
                best = (bic, xi, thr)
        coef[k], chosen = best[1] * ys / scale, chosen + [float(best[2])]
    seconds = time.perf_counter() - t0

    syms = sp.symbols(list(names) + [f"{a}_dot" for a in names])
    exprs = [sp.Mul(*[s ** int(p) for s, p in zip(syms, row)]) for row in powers]
    monos = [str(e) for e in exprs]
    odd = powers[:, n:].sum(axis=1) % 2 == 1
    law = coef * odd[None, :]
    terms = {(k, monos[j]) for k in range(n) for j in range(len(monos)) if law[k, j] != 0}
    formula = {
        f"{names[k]}_ddot": str(
            sp.Add(*[sp.Float(law[k, j], 4) * exprs[j] for j in range(len(exprs)) if law[k, j] != 0])
        )
        for k in range(n)
    }

    def predict(qq, qqd, tt=None):
        x = np.hstack([np.asarray(qq, float).reshape(-1, n), np.asarray(qqd, float).reshape(-1, n)])
        return np.prod(x[:, None, :] ** powers[None], axis=2) @ law.T

    return {
        "terms": terms,
        "formula": formula,
        "predict": predict,
        "seconds": seconds,
        "coefficients": {
            (k, monos[j]): float(coef[k, j]) for k in range(n) for j in range(len(monos)) if coef[k, j] != 0
        },
        "threshold": chosen,
    }


if __name__ == "__main__":
    from scipy.integrate import solve_ivp

    gamma, dt = 0.05, 0.1
    ts = np.arange(0.0, 60.0 + dt / 2, dt)
    T, Q, ID = [], [], []
    for i, y0 in enumerate([(1.0, 0.0), (-0.5, 1.0), (2.0, -0.5)]):
        sol = solve_ivp(lambda _t, y: [y[1], -y[0] - gamma * y[1]], (0, 60), y0, t_eval=ts, rtol=1e-11, atol=1e-12)
        T.append(ts), Q.append(sol.y[0]), ID.append(np.full(len(ts), i))
    t, q, traj = np.concatenate(T), np.concatenate(Q)[:, None], np.concatenate(ID)
    for label, qq in [("clean", q), ("noise 1e-3", q + 1e-3 * np.random.default_rng(0).standard_normal(q.shape))]:
        res = sindy_law(t, qq, traj, ["x"])
        print(f"[{label}] law: x_ddot = {res['formula']['x_ddot']}   (truth: -0.05*x_dot)")
        print(f"    full fit: {res['coefficients']}   threshold={res['threshold']}   {res['seconds']:.3f} s")
        c = res["coefficients"].get((0, "x_dot"), 0.0)
        ok = res["terms"] == {(0, "x_dot")} and abs(c + gamma) < 0.1 * gamma
        print(f"    check law == -0.05*x_dot: {'OK' if ok else 'FAIL'} (x_dot coefficient {c:+.5f})")
