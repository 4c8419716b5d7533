r"""The joint weighted least-squares fit of one candidate law with the conservative model, and its statistics.

**Joint fit under the paper's principle.** For each candidate, (α, β) minimise Σ w²(q̈ − f_c − g)² + μ w̄² Σ g² with
μ = :data:`MU` (the paper's L_e + λ L_b with λ ≪ 1, in the 2-norm; w̄² the mean of w², so the penalty weighs f_n
alike in every coordinate, as the paper's L_b does): where the conservative model and the law can both
explain a piece of the data (a gyroscopic force is also the antisymmetric part of a full Γ), the conservative model
takes it and the law is the *minimal* non-conservative remainder. θ is found by variable projection (scipy
least_squares over θ, β and α solved linearly at each θ). Weights w are 1/(estimated q̈ error) per row and coordinate
where given, else 1/rms(q̈) per coordinate.

**Held-out error and uncertainty.** The fit is linearised at its optimum (Jacobian J over α, β, θ); the data
are cut into folds — whole trajectories when there are ≥ 3, else :data:`N_FOLDS` contiguous stretches of each
trajectory — and each fold is predicted by the fit to the others (one Gauss–Newton step from the optimum: exact for
the linear families). Coefficient uncertainties are the spread of a moving-block bootstrap over the rows (blocks of 2τ
samples, τ the integrated autocorrelation time of the residuals: derivative errors are correlated over the
differentiation window), the larger of it and the model-based standard error inflated by √τ.
"""

from __future__ import annotations

import math

import numpy as np

from nnphd.explain.families import Family

__all__ = ["MU", "N_BOOT", "N_FOLDS"]

MU = 1e-6  # weight of the minimal-f_n penalty (the paper's λ < 1; tiny: it only decides between exact ties)
N_FOLDS = 5  # held-out folds per trajectory when there are fewer than 3 trajectories
N_BOOT = 200


class JointProblem:
    """The weighted joint least-squares problem on the data rows."""

    def __init__(self, q, qd, qdd, t, w, C, angles):
        self.q, self.qd, self.qdd, self.t, self.w, self.C, self.angles = q, qd, qdd, t, w, C, angles
        self.N, self.n = q.shape
        self.yw = (qdd * w).reshape(-1)
        # the penalty weighs f_n alike in every coordinate and row (the paper's minimal |f_n|): with the data's
        # per-coordinate weights the "minimal" law would trade a gyroscopic piece in when the weights differ
        wf = w.reshape(-1)
        self.pw = float(np.sqrt(np.mean(wf**2))) / wf
        self.Cw = (C * w[:, :, None]).reshape(self.N * self.n, -1)
        cn = np.sqrt(np.mean(self.Cw**2, axis=0))
        self.c_scale = np.where(cn > 0, cn, 1.0)
        # the conservative library is rank-deficient by construction (sin² + cos² = 1, sin 2θ = 2 sin θ cos θ, …):
        # work in an orthonormal basis Q of its column space, so that the law is fitted to the part of the data the
        # conservative model cannot explain and only the penalty decides between exactly equivalent splits
        U, S, Vt = np.linalg.svd(self.Cw / self.c_scale, full_matrices=False)
        keep = S > 1e-10 * (S[0] if len(S) else 1.0)
        self.Q, self._S, self._V = U[:, keep], S[keep], Vt[keep].T
        self.Z = self.Q * self._S  # = (Cw / c_scale) V: the reduced conservative columns (for the Jacobian)

    def _perp(self, x):
        return x - self.Q @ (self.Q.T @ x)

    def design(self, fam: Family | None, th):
        if fam is None:
            return np.zeros((self.N * self.n, 0)), np.zeros(self.N * self.n)
        B = np.asarray(fam.basis(np, np.asarray(th, float), self.q, self.qd, self.t), float)
        Bw = (B * self.w[:, :, None]).reshape(self.N * self.n, -1)
        off = np.zeros(self.N * self.n)
        if fam.fixed is not None:
            off = (np.asarray(fam.fixed(np, np.asarray(th, float), self.q, self.qd, self.t)) * self.w).reshape(-1)
        return Bw, off

    def solve(self, Bw, off):
        """(α, β, data residual, penalty residual) of min |y − Cα − Bβ − off|² + μ|Bβ + off|²."""
        K = Bw.shape[1]
        sm = math.sqrt(MU)
        if K:
            bn = np.sqrt(np.mean(Bw**2, axis=0))
            bn = np.where(bn > 0, bn, 1.0)
            A = np.concatenate([self._perp(Bw) / bn, sm * self.pw[:, None] * Bw / bn])
            rhs = np.concatenate([self._perp(self.yw - off), -sm * self.pw * off])
            b = np.linalg.lstsq(A, rhs, rcond=1e-12)[0] / bn
        else:
            b = np.zeros(0)
        law = Bw @ b + off
        y = self.yw - law
        a = (self._V @ ((self.Q.T @ y) / self._S)) / self.c_scale
        r = self._perp(y)
        return a, b, r, -sm * self.pw * law

    def fit(self, fam: Family | None, ctx) -> dict:
        if fam is None or not fam.nl_names:
            th = np.zeros(0)
            Bw, off = self.design(fam, th)
            a, b, r, rp = self.solve(Bw, off)
            return {"theta": th, "alpha": a, "beta": b, "r": r, "rp": rp}
        from scipy.optimize import least_squares

        def res(th):
            Bw, off = self.design(fam, th)
            _, _, r, rp = self.solve(Bw, off)
            out = np.concatenate([r, rp])
            return np.where(np.isfinite(out), out, 1e150)

        lo, hi = (np.asarray(x, float) for x in fam.nl_bounds)
        best = None
        for th0 in fam.nl_starts(ctx):
            th0 = np.clip(np.asarray(th0, float), lo + 1e-12, np.where(np.isfinite(hi), hi - 1e-12, np.inf))
            try:
                sol = least_squares(
                    res, th0, bounds=(lo, hi), method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12, max_nfev=200
                )
            except (ValueError, np.linalg.LinAlgError, FloatingPointError):
                continue
            if np.isfinite(sol.cost) and (best is None or sol.cost < best.cost):
                best = sol
        if best is None:
            return {}
        th = best.x
        Bw, off = self.design(fam, th)
        a, b, r, rp = self.solve(Bw, off)
        return {"theta": th, "alpha": a, "beta": b, "r": r, "rp": rp}

    def jacobian(self, fam: Family | None, fit: dict):
        """Per-row Jacobian (N, 2n, P) over (α, β, θ) of the model rows (data and penalty) and residuals (N, 2n)."""
        th, b = fit["theta"], fit["beta"]
        Bw, off = self.design(fam, th)
        sm = math.sqrt(MU)
        cols = [self.Z, Bw]
        pcols = [np.zeros_like(self.Z), sm * self.pw[:, None] * Bw]
        for i in range(len(th)):
            h = 1e-6 * max(1.0, abs(th[i]))
            tp = th.copy()
            tp[i] += h
            Bp, offp = self.design(fam, tp)
            d = ((Bp @ b + offp) - (Bw @ b + off)) / h
            cols.append(d[:, None])
            pcols.append(sm * (self.pw * d)[:, None])
        J = np.concatenate(
            [
                np.concatenate(cols, axis=1).reshape(self.N, self.n, -1),
                np.concatenate(pcols, axis=1).reshape(self.N, self.n, -1),
            ],
            axis=1,
        )
        R = np.concatenate([fit["r"].reshape(self.N, self.n), fit["rp"].reshape(self.N, self.n)], axis=1)
        return J, R


def solve_or_lstsq(A, b):
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


def ridge_regularised(G):
    return G + 1e-12 * max(float(np.trace(G)) / max(G.shape[0], 1), 1e-300) * np.eye(G.shape[0])


def trajectory_segments(traj) -> list[np.ndarray]:
    """The row indices of each trajectory: one array per run of equal ids in ``traj`` (the rows in file order)."""
    traj = np.asarray(traj)
    cuts = np.flatnonzero(np.diff(traj) != 0) + 1
    return np.split(np.arange(len(traj)), cuts)


def heldout_folds(segs) -> tuple[list[np.ndarray], str]:
    if len(segs) >= 3:
        k = min(len(segs), 10)
        groups = np.array_split(np.arange(len(segs)), k)
        return [np.concatenate([segs[i] for i in g]) for g in groups], f"{k} folds of whole trajectories"
    folds = [np.concatenate(parts) for parts in zip(*[np.array_split(s, N_FOLDS) for s in segs])]
    return folds, f"{N_FOLDS} contiguous stretches of each trajectory"


def autocorrelation_time(r: np.ndarray, segs) -> float:
    """Integrated autocorrelation time of residuals (N, n) within trajectories (summed up to the first ρ < 0.05)."""
    num = np.zeros(64)
    den = 0.0
    for s in segs:
        x = r[s] - r[s].mean(axis=0)
        den += float(np.sum(x * x))
        for k in range(1, min(64, len(s))):
            num[k] += float(np.sum(x[k:] * x[:-k]))
    if den <= 0:
        return 1.0
    rho = num / den
    tau = 1.0
    for k in range(1, 64):
        if rho[k] < 0.05:
            break
        tau += 2 * rho[k]
    return float(min(max(tau, 1.0), max(1.0, sum(len(s) for s in segs) / 20)))


def linear_stats(J, R, folds, segs, tau, n_boot, seed, P_law_idx):
    """Held-out MSE by one Gauss–Newton step per fold, bootstrap and model covariance of the law parameters."""
    N, rows2, P = J.shape
    n = rows2 // 2
    # sums of the rows' J_sᵀJ_s over a fold or a bootstrap block are products of the stacked rows (BLAS), never the
    # (N, P, P) stack of per-row products: that is P² numbers a row (150 MB for a 704-row, 163-parameter table of a
    # 3-D orbit), and fresh memory of that size took 1–5 s to touch on these machines
    J2, R2 = J.reshape(N * rows2, P), R.reshape(-1)
    G, h = J2.T @ J2, J2.T @ R2
    sse = 0.0
    m = 0
    for f in folds:
        Jf = J[f].reshape(-1, P)
        d = solve_or_lstsq(ridge_regularised(G - Jf.T @ Jf), h - Jf.T @ R[f].reshape(-1))
        pred = R[f, :n] - J[f, :n] @ d
        sse += float(np.sum(pred**2))
        m += pred.size
    mse = sse / max(m, 1)
    # moving-block bootstrap over rows within trajectories: each block's sums at once (its rows padded with zero rows
    # to the block length, one batched product), every replicate's as its blocks' counts times them (the same draws
    # as one replicate after another)
    L = max(1, math.ceil(2 * tau))
    blocks = [s[i : i + L] for s in segs for i in range(0, len(s), L)] if n_boot > 0 else []
    reps = []
    if blocks:
        B = len(blocks)
        idx = np.full((B, L), N, np.intp)  # row N: the zero row
        for i, blk in enumerate(blocks):
            idx[i, : len(blk)] = blk
        Jb = np.concatenate([J, np.zeros((1, rows2, P))])[idx].reshape(B, L * rows2, P)
        Rb = np.concatenate([R, np.zeros((1, rows2))])[idx].reshape(B, L * rows2)
        Gb = np.matmul(Jb.transpose(0, 2, 1), Jb).reshape(B, P * P)
        hb = np.matmul(Jb.transpose(0, 2, 1), Rb[..., None])[..., 0]
        del Jb
        draws = np.random.default_rng(seed).integers(0, B, (n_boot, B))
        counts = np.zeros((n_boot, B))
        np.add.at(counts, (np.repeat(np.arange(n_boot), B), draws.ravel()), 1.0)
        hrep = counts @ hb
        for k0 in range(0, n_boot, 32):  # 32 replicates' P×P sums at a time
            Grep = (counts[k0 : k0 + 32] @ Gb).reshape(-1, P, P)
            reps += [solve_or_lstsq(ridge_regularised(g), hrep[k0 + k]) for k, g in enumerate(Grep)]
    reps = np.asarray(reps)[:, P_law_idx] if len(P_law_idx) else np.zeros((n_boot, 0))
    se_boot = reps.std(axis=0) if n_boot > 1 else np.full(len(P_law_idx), np.inf)
    dof = max(N * n - P, 1)
    s2 = float(np.sum(R[:, :n] ** 2)) / dof
    cov = s2 * np.linalg.pinv(ridge_regularised(G))
    se_model = np.sqrt(np.maximum(np.diag(cov)[P_law_idx], 0.0) * tau) if len(P_law_idx) else np.zeros(0)
    return mse, se_boot, se_model
