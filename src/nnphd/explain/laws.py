r"""The law of the non-conservative force: candidate laws fitted *jointly* with a conservative model, ranked by
held-out error with a parsimony penalty, each with bootstrap uncertainties (:func:`rank_laws`).

Model. q̈ = f_c(q, q̇) + g(q, q̇, t; β, θ), fitted to the rows (q, q̇, q̈, t) of the data:

* **f_c, the conservative part**, linear in its coefficients α: :mod:`nnphd.explain.conservative`.
* **g, the candidate law**, linear in β given a few nonlinear parameters θ: :mod:`nnphd.explain.families` (here:
  the drive's start frequencies from the conservative residual's spectrum, :func:`drive_start_omegas`, and the supports
  of the sparse polynomial, thresholded jointly with f_c, :func:`_sparse_supports`).
* **the joint fit** under the paper's minimal-f_n principle, held-out error and bootstrap uncertainties:
  :mod:`nnphd.explain.jointfit`.
* **the ranking** (IC, ties, eligibility, the winner): :mod:`nnphd.explain.table`.

The same candidates are re-fitted to the positions by multiple shooting in :mod:`nnphd.explain.trajectory`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from nnphd.explain.conservative import conservative_basis
from nnphd.explain.families import Family, families, odd_monomials, parse_law, perturber_family, sparse_family
from nnphd.explain.jointfit import (
    MU,
    N_BOOT,
    JointProblem,
    autocorrelation_time,
    heldout_folds,
    linear_stats,
    trajectory_segments,
)
from nnphd.explain.table import (
    IC_TIE,
    BaseFit,
    Candidate,
    LawTable,
    law_row,
    overdispersion_c_hat,
    overdispersion_ratio,
    relative_to_zero,
    select_law,
    zero_row,
)

__all__ = ["CandidateSet", "ConservativeBase", "PointwiseSettings", "rank_laws"]


LS_CELLS = 2**21  # complex cells per temporary of :func:`lomb_scargle_grid` (32 MB)


def _grid_sums(t, y, w0: float, dw: float, M: int):
    """Σ_j y_j·exp(i·w_k·t_j) for the M evenly spaced frequencies w_k = w0 + k·dw. With k = a·B + b the phase
    factors as exp(i(w0 + aB·dw)t)·exp(i·b·dw·t): two tables of ~√M rows each, their product summed over the samples
    by one matrix product — N·2√M complex exponentials instead of N·M, each phase computed directly (no recurrence:
    the same rounding as the direct sum). Samples in chunks of at most ~LS_CELLS cells per table."""
    B = max(1, math.isqrt(max(M - 1, 0)) + 1)
    A_rows = -(-M // B)
    step = max(1, LS_CELLS // (A_rows + B))
    Z = np.zeros((A_rows, B), complex)
    wa = w0 + np.arange(A_rows) * B * dw
    wb = np.arange(B) * dw
    for i in range(0, len(t), step):
        tt, yy = t[i : i + step], y[i : i + step]
        Z += (yy * np.exp(1j * np.outer(wa, tt))) @ np.exp(1j * np.outer(wb, tt)).T
    return Z.reshape(-1)[:M]


def lomb_scargle_grid(t, y, w0: float, dw: float, M: int) -> np.ndarray:
    """scipy.signal.lombscargle(t, y, w, normalize=False) on the grid w_k = w0 + k·dw (k < M), y centred by the
    caller: ½[(Σy cos(wt−τ))²/Σcos²(wt−τ) + (Σy sin(wt−τ))²/Σsin²(wt−τ)], with τ from Σexp(2iwt) — the same formula
    and the same floor on the two normalisations (scipy's machine epsilon of the mean), from the sums of
    :func:`_grid_sums`: N·2√M complex exponentials and one matrix product instead of N·M sines and cosines
    (3001 samples, 20000 frequencies: 0.7 s against scipy's 5 s per component). The time origin is moved to the middle of the record (the power does not depend on it;
    smaller phases, smaller rounding)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    N = len(t)
    tc = t - 0.5 * (t.min() + t.max())
    Z = _grid_sums(tc, y, w0, dw, M)
    E2 = _grid_sums(tc, np.ones(N), 2 * w0, 2 * dw, M)
    rot = np.exp(-0.5j * np.angle(E2))  # exp(−iτ), τ = ½·arg Σexp(2iwt)
    Zr = Z * rot
    half = 0.5 * np.abs(E2)
    eps = np.finfo(float).epsneg * N
    CC = np.maximum(0.5 * N + half, eps)
    SS = np.maximum(0.5 * N - half, eps)
    return 0.5 * (Zr.real**2 / CC + Zr.imag**2 / SS)


def drive_start_omegas(t, r, segs, n_peaks: int = 3) -> list[float]:
    """Angular frequencies of the largest peaks of the residual's Lomb–Scargle spectrum (all components)."""
    dts = np.concatenate([np.diff(t[s]) for s in segs if len(s) > 1])
    dt = float(np.median(dts[dts > 0])) if np.any(dts > 0) else 1.0
    span = float(np.max([np.ptp(t[s]) for s in segs]))
    if span <= 0:
        return [1.0]
    M = int(min(20000, max(200, 8 * span / dt)))
    w = np.linspace(2 * np.pi / span, np.pi / dt, M)
    P = np.zeros_like(w)
    for j in range(r.shape[1]):
        y = r[:, j] - r[:, j].mean()
        if np.any(y):
            P += lomb_scargle_grid(t, y, float(w[0]), float((w[-1] - w[0]) / (M - 1)), M)
    peaks = [i for i in range(1, len(w) - 1) if P[i] >= P[i - 1] and P[i] >= P[i + 1]]
    peaks.sort(key=lambda i: -P[i])
    return [float(w[i]) for i in peaks[:n_peaks]] or [float(w[int(np.argmax(P))])]


def _sparse_supports(prob: JointProblem, mons_n: int, n: int) -> list[np.ndarray]:
    """Sequentially thresholded joint least squares over a grid of thresholds: the distinct supports (n × M)."""
    full = np.ones((n, mons_n), bool)
    fam = sparse_family(n, [f"q{i}" for i in range(n)], full)
    Bw, off = prob.design(fam, np.zeros(0))
    bn = np.sqrt(np.mean(Bw**2, axis=0))
    bn = np.where(bn > 0, bn, 1.0)
    scale = float(np.sqrt(np.mean(prob.yw**2))) or 1.0
    sups, seen = [], set()
    for thr in np.geomspace(1e-4, 0.3, 25):
        keep = np.ones(Bw.shape[1], bool)
        for _ in range(10):
            _, b, _, _ = prob.solve(Bw[:, keep], off)
            bb = np.zeros(Bw.shape[1])
            bb[keep] = b
            new = keep & (np.abs(bb) * bn >= thr * scale)
            if np.array_equal(new, keep):
                break
            keep = new
            if not keep.any():
                break
        if not keep.any():
            continue
        sup = keep.reshape(n, mons_n)
        key = sup.tobytes()
        if key not in seen:
            seen.add(key)
            sups.append(sup)
    return sups


@dataclass(frozen=True, eq=False)
class ConservativeBase:
    """The conservative model the candidate laws are fitted jointly with: ``fc`` (N, n) a conservative force on the
    rows whose scale is fitted (e.g. the LNN's; None: none); ``library`` the conservative correction library added
    to it (True: the full one; "minimal": the uniform field only, "short", "vertical":
    :func:`nnphd.explain.conservative.conservative_basis`; False: fc's scale alone — for a system's own feature
    Lagrangian); ``columns`` (N, n, K) more conservative columns, e.g. the derivatives ∂f_c/∂c of a feature
    Lagrangian's force by its coefficients, so that the joint fit re-fits c (linearised at the trained c) — a table
    built with them is for the pointwise ranking only."""

    fc: np.ndarray | None = None
    library: bool | str = True
    columns: np.ndarray | None = None

    def take(self, keep: np.ndarray) -> ConservativeBase:
        """The base on the rows ``keep`` (fc and the columns, where given)."""
        fc = None if self.fc is None else np.asarray(self.fc, float)[keep]
        columns = None if self.columns is None else np.asarray(self.columns, float)[keep]
        return ConservativeBase(fc, self.library, columns)


@dataclass(frozen=True)
class CandidateSet:
    """Which candidate laws are ranked: ``include`` the families to try — built-in keys and
    :class:`~nnphd.explain.families.Family` objects of your own, ranked as they are (None: every built-in one but
    the opt-in ``"perturber"``); ``user_laws`` SymPy strings (:func:`nnphd.explain.families.parse_law`), always
    ranked; ``perturber``: add the perturber family (n = 2 orbits)."""

    include: Sequence[str | Family] | None = None
    user_laws: Sequence[str] = ()
    perturber: bool = False


@dataclass(frozen=True)
class PointwiseSettings:
    """How the pointwise ranking measures: ``n_boot`` bootstrap replicates of the uncertainties, drawn with
    ``seed``; rows beyond ``max_rows`` are thinned evenly."""

    n_boot: int = N_BOOT
    seed: int = 0
    max_rows: int = 20000


def rank_laws(
    data,
    traj=None,
    *,
    names: Sequence[str] | None = None,
    angles=None,
    qdd_err=None,
    base: ConservativeBase = ConservativeBase(),
    candidates: CandidateSet = CandidateSet(),
    settings: PointwiseSettings = PointwiseSettings(),
) -> LawTable:
    """Fit every candidate law jointly with the conservative model and rank them (see the module docstring).

    data: the rows — q, qd, qdd (N, n) and t (N,), e.g. a :class:`nnphd.engine.data.Dataset` (its fc and fn are not
    used); traj (N,) trajectory ids (rows of a trajectory contiguous; None: one trajectory); names: coordinate names
    (default q1…); angles: n booleans; qdd_err (N, n) per-row q̈ errors (weights); base: the conservative model
    (:class:`ConservativeBase`: a force to scale, the correction library, more columns); candidates: the laws to
    rank (:class:`CandidateSet`); settings: the bootstrap and the row limit (:class:`PointwiseSettings`).
    """
    q, qd, qdd, t = (np.asarray(a, float) for a in (data.q, data.qd, data.qdd, data.t))
    if q.ndim != 2 or qd.shape != q.shape or qdd.shape != q.shape or t.shape != (q.shape[0],):
        raise ValueError(f"q, qd, qdd must be (N, n) and t (N,); got {q.shape}, {qd.shape}, {qdd.shape}, {t.shape}")
    N, n = q.shape
    names = list(names or [f"q{i + 1}" for i in range(n)])
    angles = np.zeros(n, bool) if angles is None else np.asarray(angles, bool)
    traj = np.zeros(N, int) if traj is None else np.asarray(traj)
    w = _row_weights(qdd, qdd_err)
    if N > settings.max_rows:
        keep = _thinned(N, settings.max_rows)
        q, qd, qdd, t, w, traj = q[keep], qd[keep], qdd[keep], t[keep], w[keep], traj[keep]
        base = base.take(keep)
        N = len(q)
    segs = trajectory_segments(traj)
    C, center, n_extra = _conservative_design(q, qd, angles, base)
    prob = JointProblem(q, qd, qdd, t, w, C, angles)
    folds, fold_desc = heldout_folds(segs)

    zero = prob.fit(None, {})
    fams, ctx = _candidates(prob, zero, segs, names, candidates)
    fits = _fit_candidates(prob, fams, ctx, zero)
    # τ from the residuals of the best in-sample fit (the most signal removed), then held-out errors
    best_in = min(fits, key=lambda x: float(np.sum(x[1]["r"] ** 2)))
    tau = autocorrelation_time(best_in[1]["r"].reshape(N, n), segs)
    n_eff = N * n / tau
    rows, stats, alphas = _score_fits(prob, fits, folds, segs, tau, settings, names)
    n_eff, tau = _information_criteria(rows, stats, n_eff, tau)
    y_rms = float(np.sqrt(np.mean(qdd**2)))
    relative_to_zero(rows, y_rms)
    rows = _best_sparse_only(rows)
    table_settings = _table_settings(settings, prob, base, names, n_extra)
    return select_law(rows, n_eff, tau, fold_desc, table_settings, base=BaseFit(alphas, center, y_rms))


def _row_weights(qdd, qdd_err) -> np.ndarray:
    """The rows' weights (N, n): 1 / the per-row q̈ errors (a missing or non-positive one: the component's median
    error, else its q̈ scatter), or without errors 1 / each component's rms q̈."""
    N, n = qdd.shape
    if qdd_err is not None:
        qdd_err = np.asarray(qdd_err, float)
        ok = np.isfinite(qdd_err) & (qdd_err > 0)
        fill = np.array(
            [np.median(qdd_err[ok[:, j], j]) if ok[:, j].any() else np.std(qdd[:, j]) or 1.0 for j in range(n)]
        )
        qdd_err = np.where(ok, qdd_err, fill[None])
        return 1.0 / qdd_err
    return np.broadcast_to(1.0 / np.maximum(np.sqrt(np.mean(qdd**2, axis=0)), 1e-300), (N, n)).copy()


def _thinned(N: int, max_rows: int) -> np.ndarray:
    """The rows kept when N rows are thinned evenly to at most ``max_rows``."""
    return np.unique(np.linspace(0, N - 1, max_rows).round().astype(int))


def _conservative_design(q, qd, angles, base: ConservativeBase):
    """The conservative columns C (N, n, K) of the joint fit — the library on standardised positions, then any given
    columns (``base``) — with the standardisation (mean, sd) and the number of given columns."""
    N, n = q.shape
    fc, library, conservative_cols = base.fc, base.library, base.columns
    sd = q.std(axis=0)
    center = (q.mean(axis=0), np.where(sd > 0, sd, 1.0))  # positions enter the conservative library standardised
    C = conservative_basis(np, q, qd, angles, None if fc is None else np.asarray(fc, float), center, library)
    n_extra = 0
    if conservative_cols is not None:
        X = np.asarray(conservative_cols, float)
        if X.ndim != 3 or X.shape[:2] != (N, n) or not np.all(np.isfinite(X)):
            raise ValueError(f"conservative_cols must be finite and (N, n, K) = ({N}, {n}, K); got {X.shape}")
        C, n_extra = np.concatenate([C, X], axis=2), X.shape[2]
    return C, center, n_extra


def _candidates(prob: JointProblem, zero, segs, names, candidates: CandidateSet):
    """The candidate families (built-in ones in ``candidates.include``, the perturber, the sparse supports, the Family
    objects in ``include``, the user's laws) and the context of their fits (the drive's start frequencies from the
    zero law's residual)."""
    q, t, w = prob.q, prob.t, prob.w
    include, perturber, user_laws = candidates.include, candidates.perturber, candidates.user_laws
    v_rms = np.sqrt(np.mean(prob.qd**2, axis=0))
    N, n = q.shape
    r0 = zero["r"].reshape(N, n) / w
    ctx = {"drive_omegas": drive_start_omegas(t, r0, segs), "q": q, "t": t, "residual": r0}
    keys = None if include is None else {k for k in include if isinstance(k, str)}
    fams = [f for f in families(n, names, v_rms) if keys is None or f.key in keys]
    if (perturber or (keys is not None and "perturber" in keys)) and n == 2:
        fams.append(perturber_family(names))
    if keys is None or "sparse" in keys:
        for sup in _sparse_supports(prob, len(odd_monomials(n)), n):
            fams.append(sparse_family(n, names, sup))
    fams += [f for f in include or () if isinstance(f, Family)]  # your own families, as they are
    fams += [parse_law(u, names) for u in user_laws]
    return fams, ctx


def _fit_candidates(prob: JointProblem, fams, ctx, zero) -> list:
    """(family, joint fit) pairs: the zero law (family None) first, then each candidate whose fit succeeded with
    finite residuals."""
    fits = [(None, zero)]
    for f in fams:
        fit = prob.fit(f, ctx)
        if fit and np.all(np.isfinite(fit["r"])):
            fits.append((f, fit))
    return fits


def _score_fits(prob: JointProblem, fits, folds, segs, tau, settings: PointwiseSettings, names):
    """Held-out errors and bootstrap uncertainties of every fit: its table row, its (held-out mse, k, overdispersion
    ratio) and its conservative coefficients (by ``id(row)``)."""
    q, qd, t = prob.q, prob.qd, prob.t
    n_boot, seed = settings.n_boot, settings.seed
    N = len(q)
    rows: list[Candidate] = []
    stats: list = []
    alphas: dict[int, np.ndarray] = {}
    Kc = prob.Z.shape[1]  # the Jacobian's conservative columns (reduced basis)
    for f, fit in fits:
        J, R = prob.jacobian(f, fit)
        law_idx = np.arange(Kc, J.shape[2])
        mse, se_b, se_m = linear_stats(J, R, folds, segs, tau, n_boot if f is not None else 0, seed, law_idx)
        stats.append(
            (
                mse,
                0 if f is None else f.k,
                overdispersion_ratio(se_b, se_m, np.concatenate([fit["beta"], fit["theta"]])),
            )
        )
        if f is None:
            row = zero_row(names, mse, N, "pointwise")
        else:
            row = law_row(f, fit["beta"], fit["theta"], np.maximum(se_b, se_m), names, mse, "pointwise")
            row.on_rows(q, qd, t)
        rows.append(row)
        alphas[id(row)] = fit["alpha"]
    return rows, stats, alphas


def _information_criteria(rows: list[Candidate], stats: list, n_eff: float, tau: float) -> tuple[float, float]:
    """Each row's IC once the overdispersion ĉ is known (from the stats of :func:`_score_fits`): n_eff / ĉ and τ·ĉ."""
    c_hat = overdispersion_c_hat([x[2] for x in stats], [x[0] for x in stats])  # IC once the overdispersion is known
    n_eff = n_eff / c_hat
    tau = tau * c_hat
    for r, (mse, k, _) in zip(rows, stats):
        r.ic = n_eff * math.log(max(mse, 1e-300)) + k * math.log(max(n_eff, 2.0))
    return n_eff, tau


def _best_sparse_only(rows: list[Candidate]) -> list[Candidate]:
    """The sparse family keeps only its best support, and not when a named family has the same formula."""
    sparse = [r for r in rows if r.key == "sparse"]
    if len(sparse) > 1:
        keep_s = min(sparse, key=lambda r: r.ic)
        rows = [r for r in rows if r.key != "sparse" or r is keep_s]
    named = {tuple(r.formula.values()) for r in rows if r.key != "sparse"}
    return [r for r in rows if r.key != "sparse" or tuple(r.formula.values()) not in named]


def _table_settings(settings: PointwiseSettings, prob: JointProblem, base: ConservativeBase, names, n_extra):
    """The table's settings, as the report shows them."""
    library = base.library
    return {
        "mu": MU,
        "ic_tie": IC_TIE,
        "n_boot": settings.n_boot,
        "seed": settings.seed,
        "rows": int(prob.N),
        "method": "pointwise",
        "conservative_columns": int(prob.C.shape[2]),
        "conservative_rank": int(prob.Z.shape[1]),
        "conservative_base": base.fc is not None,
        "names": names,
        "library": library if library in ("minimal", "short", "vertical") else bool(library),
        "conservative_extra": int(n_extra),
    }
