"""Parametric hypothesis fits for a learned non-conservative acceleration f_n (paper §III.A.3, Table II).

Each fit takes samples of f_n (N, n) with the coordinates they were evaluated at and returns a
:class:`~nnphd.explain.law.Law` (status "candidate": a hypothesis fitted, not claimed) with the best parameters,
their standard errors from the Jacobian at the optimum (cov = s² (JᵀJ)⁻¹ with s² = RSS / (N·n − p)), the residual
``rms`` and ``rel_rms`` (over the rms of f_n) and the formula of the whole vector as one entry ``"f_n"``
(:meth:`~nnphd.explain.law.Law.text` reads "f_n = …"; :meth:`~nnphd.explain.law.Law.to_fit_dict` is results.json's
``parametric``).

* :func:`fit_linear_friction` — f_n ≈ −Γ q̇ (full n×n Γ, linear least squares);
* :func:`fit_drag_power` — f_n ≈ −k (|q̇|²)^m q̇;
* :func:`fit_perturber` — f_n ≈ GM (r_p(t) − q)/|r_p(t) − q|³, r_p(t) = R (cos(ωt+φ), sin(ωt+φ)).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from nnphd.explain.law import Law, LawStatus

TITLES = {  # the fits' titles (Law.title), by key
    "linear_friction": "linear friction −Γ q̇ (full n×n Γ)",
    "drag_power": "power-law drag −k (|q̇|²)^m q̇",
    "perturber": "perturber GM (r_p(t) − q)/|r_p(t) − q|³ on a circular orbit",
}


# ---------------------------------------------------------------------------------------------------- helpers
def _as_array(name: str, a, ndim: int) -> np.ndarray:
    try:
        arr = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name} must be a numeric array: {e}") from None
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise ValueError(f"{name} must not be empty")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains non-finite values")
    return arr


def _same_shape(name_a: str, a: np.ndarray, name_b: str, b: np.ndarray) -> None:
    if a.shape != b.shape:
        raise ValueError(f"{name_a} shape {a.shape} does not match {name_b} shape {b.shape}")


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _stderr_from_jac(jac: np.ndarray, resid: np.ndarray) -> np.ndarray:
    """Standard errors sqrt(diag(s² (JᵀJ)⁻¹)), s² = RSS / (m − p); inf where undetermined."""
    m, p = jac.shape
    dof = m - p
    if dof <= 0:
        return np.full(p, np.inf)
    s2 = float(resid @ resid) / dof
    jtj = jac.T @ jac
    try:
        cov = s2 * np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        cov = s2 * np.linalg.pinv(jtj)
    d = np.diag(cov)
    return np.where(d >= 0, np.sqrt(np.abs(d)), np.inf)


def _make_fit(name, names, values, errors, resid, fn, formula) -> Law:
    """The fit as a :class:`Law`: ``formula`` is the right-hand side of "f_n = …"."""
    rms = _rms(resid)
    scale = _rms(fn)
    rel = rms / scale if scale > 0 else (0.0 if rms == 0 else np.inf)
    return Law(
        key=name,
        title=TITLES[name],
        formula={"f_n": formula},
        latex={},
        params={k: float(v) for k, v in zip(names, values)},
        stderr={k: float(e) for k, e in zip(names, errors)},
        method="pointwise",
        status=LawStatus.CANDIDATE,
        rms=float(rms),
        rel_rms=float(rel),
    )


def _wrap(phi: float) -> float:
    """Wrap an angle to (−π, π]."""
    w = float(np.mod(phi + np.pi, 2 * np.pi) - np.pi)  # [−π, π)
    return np.pi if w <= -np.pi else w


# ---------------------------------------------------------------------------------------------------- friction
def fit_linear_friction(qd, fn) -> Law:
    """Fit f_n ≈ −Γ q̇ with a full n×n matrix Γ (params ``Gamma_ij``, indices from 1)."""
    qd = _as_array("qd", qd, 2)
    fn = _as_array("fn", fn, 2)
    _same_shape("qd", qd, "fn", fn)
    N, n = qd.shape
    X = -qd
    # f_n[:, i] = X @ Γ[i, :]  →  one linear system per output component, solved together.
    G_T, *_ = np.linalg.lstsq(X, fn, rcond=None)  # (n, n): column i holds Γ[i, :]
    gamma = G_T.T
    resid = fn + qd @ gamma.T
    p = n * n
    dof = N * n - p
    if dof > 0:
        s2 = float(np.sum(resid**2)) / dof
        xtx_inv = np.linalg.pinv(X.T @ X)
        row_err = np.sqrt(np.abs(s2 * np.diag(xtx_inv)))  # same for every row i
        errs = np.tile(row_err, (n, 1))
    else:
        errs = np.full((n, n), np.inf)
    names = [f"Gamma_{i + 1}{j + 1}" for i in range(n) for j in range(n)]
    rows = "; ".join(" ".join(f"{gamma[i, j]:+.6g}" for j in range(n)) for i in range(n))
    formula = f"-Gamma q_dot, Gamma = [{rows}]"
    return _make_fit("linear_friction", names, gamma.ravel(), errs.ravel(), resid, fn, formula)


# ---------------------------------------------------------------------------------------------------- drag power
def fit_drag_power(qd, fn, m_bounds=(0.0, 10.0)) -> Law:
    """Fit f_n ≈ −k (|q̇|²)^m q̇ for (k, m), m constrained to ``m_bounds``."""
    qd = _as_array("qd", qd, 2)
    fn = _as_array("fn", fn, 2)
    _same_shape("qd", qd, "fn", fn)
    lo, hi = (float(m_bounds[0]), float(m_bounds[1]))
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ValueError(f"m_bounds must be finite with lower < upper, got {m_bounds!r}")
    s = np.sum(qd**2, axis=1)  # |q̇|²
    fabs = np.linalg.norm(fn, axis=1)

    # Start: |f| = |k| s^(m + 1/2)  →  log|f| = log|k| + (m + 1/2) log s, over samples where both are positive.
    ok = (s > 0) & (fabs > 0)
    m0, k0 = 0.5 * (lo + hi), 0.0
    if np.count_nonzero(ok) >= 2 and np.ptp(np.log(s[ok])) > 0:
        slope, intercept = np.polyfit(np.log(s[ok]), np.log(fabs[ok]), 1)
        m0 = slope - 0.5
        k0 = float(np.exp(intercept))
    m0 = float(np.clip(m0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo)))
    sign = -1.0 if np.sum(fn * qd) > 0 else 1.0  # anti-damping gives negative k
    # With m fixed the model is linear in k: take the exact k for the start.
    basis = -(np.where(s > 0, s, 1.0) ** m0 * (s > 0))[:, None] * qd
    bb = float(np.sum(basis**2))
    k0 = float(np.sum(basis * fn) / bb) if bb > 0 else sign * k0

    def resid(x):
        k, m = x
        sm = np.where(s > 0, np.where(s > 0, s, 1.0) ** m, 0.0)
        return (fn + k * sm[:, None] * qd).ravel()

    def jac(x):
        k, m = x
        ss = np.where(s > 0, s, 1.0)
        sm = np.where(s > 0, ss**m, 0.0)
        dk = (sm[:, None] * qd).ravel()
        dm = (k * (sm * np.log(ss))[:, None] * qd).ravel()
        return np.column_stack([dk, dm])

    res = least_squares(
        resid,
        [k0, m0],
        jac=jac,
        bounds=([-np.inf, lo], [np.inf, hi]),
        method="trf",
        x_scale="jac",
        xtol=1e-14,
        ftol=1e-14,
        gtol=1e-14,
        max_nfev=2000,
    )
    k, m = res.x
    r = resid(res.x)
    errs = _stderr_from_jac(jac(res.x), r)
    formula = f"-{k:.6g} (|q_dot|^2)^{m:.6g} q_dot"
    return _make_fit("drag_power", ["k", "m"], [k, m], errs, r, fn, formula)


# ---------------------------------------------------------------------------------------------------- perturber
def _planet_field(q, t, R, omega, phi):
    """g = (r_p − q)/|r_p − q|³ for each sample; returns (g, d, dist)."""
    ang = omega * t + phi
    rp = R * np.column_stack([np.cos(ang), np.sin(ang)])
    d = rp - q
    dist = np.linalg.norm(d, axis=1)
    return d / dist[:, None] ** 3, d, dist


def _perturber_inputs(q, t, fn, gm_central: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The perturber fit's inputs checked and as arrays: (q (N, 2), t (N,), fn (N, 2)); ValueError otherwise."""
    q = _as_array("q", q, 2)
    fn = _as_array("fn", fn, 2)
    t = _as_array("t", t, 1)
    if q.shape[1] != 2:
        raise ValueError(f"q must have shape (N, 2) for the perturber fit, got {q.shape}")
    _same_shape("q", q, "fn", fn)
    if t.shape[0] != q.shape[0]:
        raise ValueError(f"t must have shape ({q.shape[0]},), got {t.shape}")
    if not (np.isfinite(gm_central) and gm_central > 0):
        raise ValueError(f"gm_central must be positive and finite, got {gm_central!r}")
    return q, t, fn


def _perturber_radii(q: np.ndarray, r_grid):
    """The start radii: ``r_grid`` checked, or by default 12 values over 0.5…4 × median |q| that keep 5 % clear of
    the data (all 12 if none does)."""
    rq = np.linalg.norm(q, axis=1)
    if r_grid is None:
        rmed = float(np.median(rq))
        if rmed <= 0:
            raise ValueError("q must not be concentrated at the origin (median |q| is 0)")
        cand = np.linspace(0.5, 4.0, 12) * rmed
        r_grid = [R for R in cand if np.min(np.abs(rq - R)) >= 0.05 * R]
        if not r_grid:
            r_grid = list(cand)
    else:
        r_grid = _as_array("r_grid", r_grid, 1)
        if np.any(r_grid <= 0):
            raise ValueError("r_grid values must be positive")
    return r_grid


def _perturber_starts(
    q, t, fn, r_grid, omega_grid, gm_central: float
) -> list[tuple[float, float, float, float, float]]:
    """Coarse starts (rss, GM, R, ω, φ), best first: GM solved linearly (clipped at 0) for each (R, ω, φ) of the
    grids (ω by default ± the Kepler frequency at R times 0.8…1.25; 8 phases)."""
    phis = np.linspace(-np.pi, np.pi, 8, endpoint=False)
    mults = np.array([0.8, 0.9, 1.0, 1.1, 1.25])

    # Coarse starts: GM solved linearly (clipped at 0) for each (R, ω, φ).
    starts = []
    fn_flat = fn.ravel()
    for R in r_grid:
        if omega_grid is None:
            wk = np.sqrt(gm_central / R**3) * mults
            omegas = np.concatenate([wk, -wk])
        else:
            omegas = omega_grid
        for w in omegas:
            for ph in phis:
                g, _, dist = _planet_field(q, t, R, w, ph)
                if np.any(dist == 0):
                    continue
                gf = g.ravel()
                gg = float(gf @ gf)
                if not np.isfinite(gg) or gg == 0:
                    continue
                gm = max(float(gf @ fn_flat) / gg, 0.0)
                rss = float(np.sum((fn_flat - gm * gf) ** 2))
                starts.append((rss, gm, float(R), float(w), float(ph)))
    if not starts:
        raise ValueError("no usable perturber start (r_grid/omega_grid put the planet on the data)")
    starts.sort(key=lambda s: s[0])
    return starts


def _perturber_model(q, t, fn):
    """The perturber model's residuals fn − GM g and their Jacobian, as functions of x = (GM, R, ω, φ)."""

    def resid(x):
        gm, R, w, ph = x
        g, _, _ = _planet_field(q, t, R, w, ph)
        return (fn - gm * g).ravel()

    def jac(x):
        gm, R, w, ph = x
        ang = w * t + ph
        c, s_ = np.cos(ang), np.sin(ang)
        g, d, dist = _planet_field(q, t, R, w, ph)
        # ∂g/∂r_p = (I − 3 d̂ d̂ᵀ)/|d|³
        inv3 = 1.0 / dist**3
        dhat = d / dist[:, None]

        def dg(drp):  # drp: (N, 2) derivative of r_p w.r.t. a parameter
            proj = np.sum(dhat * drp, axis=1)
            return (drp - 3.0 * dhat * proj[:, None]) * inv3[:, None]

        drp_R = np.column_stack([c, s_])
        drp_ph = R * np.column_stack([-s_, c])
        drp_w = drp_ph * t[:, None]
        cols = [-g.ravel(), -gm * dg(drp_R).ravel(), -gm * dg(drp_w).ravel(), -gm * dg(drp_ph).ravel()]
        return np.column_stack(cols)

    return resid, jac


def _best_perturber_refit(resid, jac, starts, n_keep: int) -> np.ndarray:
    """Bounded least squares from the ``n_keep`` best starts (at least one); the parameters (GM, R, ω, φ) of the
    lowest finite cost. ValueError if every start fails."""
    lower = [0.0, 1e-12, -np.inf, -np.inf]
    upper = [np.inf, np.inf, np.inf, np.inf]
    best = None
    for _, gm0, R0, w0, ph0 in starts[: max(1, int(n_keep))]:
        x0 = np.array([max(gm0, 1e-12), R0, w0, ph0])
        try:
            res = least_squares(
                resid,
                x0,
                jac=jac,
                bounds=(lower, upper),
                method="trf",
                x_scale="jac",
                xtol=1e-13,
                ftol=1e-13,
                gtol=1e-13,
                max_nfev=500,
            )
        except (ValueError, FloatingPointError):
            continue
        r = resid(res.x)
        if not np.all(np.isfinite(r)):
            continue
        cost = float(r @ r)
        if best is None or cost < best[0]:
            best = (cost, res.x.copy())
    if best is None:
        raise ValueError("perturber fit failed from every start")
    return best[1]


def fit_perturber(q, t, fn, r_grid=None, omega_grid=None, gm_central: float = 1.0, n_keep: int = 5) -> Law:
    """Fit a circularly orbiting point-mass perturber: f_n ≈ GM (r_p(t) − q)/|r_p(t) − q|³ (n = 2 only).

    ``r_grid``: start radii (default 12 values over 0.5…4 × median |q|, skipping radii that come within 5 % of
    the data). ``omega_grid``: start angular velocities (default ± the Kepler frequency sqrt(gm_central/R³)
    times 0.8, 0.9, 1, 1.1, 1.25 for each R). Negative ω is a retrograde perturber.
    """
    q, t, fn = _perturber_inputs(q, t, fn, gm_central)
    r_grid = _perturber_radii(q, r_grid)
    if omega_grid is not None:
        omega_grid = _as_array("omega_grid", omega_grid, 1)
    starts = _perturber_starts(q, t, fn, r_grid, omega_grid, gm_central)
    resid, jac = _perturber_model(q, t, fn)
    gm, R, w, ph = _best_perturber_refit(resid, jac, starts, n_keep)
    ph = _wrap(ph)
    x = np.array([gm, R, w, ph])
    r = resid(x)
    errs = _stderr_from_jac(jac(x), r)
    formula = f"{gm:.6g} (r_p - q)/|r_p - q|^3, r_p(t) = {R:.6g} (cos({w:.6g} t {ph:+.6g}), sin({w:.6g} t {ph:+.6g}))"
    return _make_fit("perturber", ["GM", "R", "omega", "phi"], x, errs, r, fn, formula)
