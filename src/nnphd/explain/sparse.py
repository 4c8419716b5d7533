"""Blind explanation by sparse regression (pysindy's STLSQ) of a learned non-conservative acceleration f_n.

No functional form is given: f_n is regressed on a library of candidate terms — polynomials of low degree in every
input (q, q̇, t), isotropic drag laws v_j·(|v|²)^m for m ≤ 6, sin/cos of t (driving) — and for each
component the sparsity threshold is swept over a grid (plus an exhaustive search of 1- and 2-term models), keeping
the model that minimises log(rms) + term_cost·terms: every term must cut the residual by 25%. The result is a SymPy expression built from the library terms.
When the best model still leaves a large residual or needs many terms, it says so (``readable = False``).
The result is a :class:`~nnphd.explain.law.Law` of status "hint" (a blind formula is a suggestion, never the law);
:meth:`~nnphd.explain.law.Law.to_hint_dict` is what results.json and report.json write under ``blind``.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from nnphd.explain.law import Law, LawStatus

READABLE_MAX_TERMS = 12
READABLE_MAX_REL_RMS = 0.25


@dataclass(frozen=True)
class BlindMethod:
    """How a blind formula was found, as its :class:`Law` names it: the ``key`` ("sparse", "genetic"), the
    ``title`` and the ``method`` in words."""

    key: str
    title: str
    method: str


SPARSE = BlindMethod(
    "sparse",
    "blind formula (sparse regression)",
    "sparse regression (pysindy STLSQ; every term must cut the residual by 25%)",
)


@dataclass(frozen=True)
class SparseLibrary:
    """The library of candidate terms of the sparse regression: polynomials to ``degree`` in every input, isotropic
    drag laws v_j·(|v|²)^m for m ≤ ``speed_powers`` (with velocities named), sin/cos(k·t) for k ≤ ``fourier`` (with
    a time named)."""

    degree: int = 3
    speed_powers: int = 6
    fourier: int = 2


def blind_law(how: BlindMethod, exprs, component_names, rel_rms: float, n_terms: int, readable: bool, note: str) -> Law:
    """A blind formula found by ``how`` as a :class:`Law` of status "hint": ``exprs`` one SymPy expression per
    component of f_n (``formula`` component → its string), ``rel_rms`` the residual rms / rms of f_n, ``n_terms`` its
    size."""
    return Law(
        key=how.key,
        title=how.title,
        formula=dict(zip(component_names, (str(e) for e in exprs))),
        latex={},
        params={},
        stderr={},
        method=how.method,
        status=LawStatus.HINT,
        rel_rms=float(rel_rms),
        n_terms=int(n_terms),
        readable=bool(readable),
        note=note,
    )


def _library(x: np.ndarray, names: Sequence[str], vel_idx: Sequence[int], t_idx: int | None, library: SparseLibrary):
    """Columns Θ(x) and their SymPy terms (no duplicates) of ``library``."""
    from nnphd._extras import require

    PolynomialLibrary = require("pysindy", "the sparse (blind) explanation").PolynomialLibrary
    degree, speed_powers, fourier = library.degree, library.speed_powers, library.fourier

    syms = {n: sp.Symbol(n) for n in names}
    cols, terms, seen = [], [], set()

    def add(block, block_names):
        lib = PolynomialLibrary(degree=block_degree, include_bias=include_bias).fit(x[:, block])
        th = lib.transform(x[:, block])
        for j, fname in enumerate(lib.get_feature_names([f"x{k}" for k in range(len(block))])):
            expr = (
                sp.Integer(1)
                if fname == "1"
                else sp.Mul(
                    *[
                        syms[block_names[int(tok.split("^")[0][1:])]] ** (int(tok.split("^")[1]) if "^" in tok else 1)
                        for tok in fname.split(" ")
                    ]
                )
            )
            if expr not in seen:
                seen.add(expr)
                cols.append(th[:, j])
                terms.append(expr)

    block_degree, include_bias = degree, True
    add(list(range(len(names))), list(names))
    if vel_idx and speed_powers:  # isotropic drag laws: v_j (|v|²)^m, shared by all components
        v2 = np.sum(x[:, vel_idx] ** 2, axis=1)
        s2 = sum(syms[names[i]] ** 2 for i in vel_idx)
        for mexp in range(1, speed_powers + 1):
            for i in vel_idx:
                expr = syms[names[i]] * s2**mexp
                cols.append(x[:, i] * v2**mexp)
                terms.append(expr)
    if t_idx is not None and fourier:
        t = syms[names[t_idx]]
        for k in range(1, fourier + 1):
            for fn, f in ((np.sin, sp.sin), (np.cos, sp.cos)):
                cols.append(fn(k * x[:, t_idx]))
                terms.append(f(k * t))
    return np.stack(cols, axis=1), terms


def _best_small_subsets(theta_n: np.ndarray, y: np.ndarray, col_rms: np.ndarray) -> list:
    """Exhaustive best 1- and 2-term least-squares models (STLSQ's greedy path can miss them with collinear terms)."""
    out = []
    g = theta_n.T @ theta_n
    b = theta_n.T @ y
    d = np.diag(g)
    ok = d > 0
    # one term
    c1 = np.where(ok, b / np.where(ok, d, 1.0), 0.0)
    rss1 = float(y @ y) - c1 * b
    j = int(np.argmin(np.where(ok, rss1, np.inf)))
    c = np.zeros(theta_n.shape[1])
    c[j] = c1[j]
    out.append((1, float(np.sqrt(max(rss1[j], 0.0) / y.size)), c / col_rms))
    # two terms
    best = (np.inf, None)
    for i in range(len(b)):
        for k in range(i + 1, len(b)):
            det = g[i, i] * g[k, k] - g[i, k] ** 2
            if det <= 1e-12 * g[i, i] * g[k, k]:
                continue
            ci = (g[k, k] * b[i] - g[i, k] * b[k]) / det
            ck = (g[i, i] * b[k] - g[i, k] * b[i]) / det
            rss = float(y @ y) - ci * b[i] - ck * b[k]
            if rss < best[0]:
                best = (rss, (i, k, ci, ck))
    if best[1] is not None:
        i, k, ci, ck = best[1]
        c = np.zeros(theta_n.shape[1])
        c[i], c[k] = ci, ck
        out.append((2, float(np.sqrt(max(best[0], 0.0) / y.size)), c / col_rms))
    return out


def regression_data(inputs: dict, fn, component_names) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(names, x (N, k), y (N, n)) of a blind regression, checked: ValueError unless fn is (N, n) and all is finite."""
    names = list(inputs)
    x = np.stack([np.asarray(inputs[k], float) for k in names], axis=1)
    y = np.asarray(fn, float)
    if y.ndim != 2 or y.shape[0] != x.shape[0] or y.shape[1] != len(component_names):
        raise ValueError(f"fn must have shape (N, {len(component_names)}) with N = {x.shape[0]}, got {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("inputs and fn must be finite")
    return names, x, y


def sparse_formula(
    inputs: dict[str, np.ndarray],
    fn: np.ndarray,
    component_names: Sequence[str],
    velocities: Sequence[str] = (),
    time: str | None = None,
    library: SparseLibrary = SparseLibrary(),
    thresholds: Sequence[float] | None = None,
    term_cost: float = float(np.log(1.25)),
) -> Law:
    """Sparse-regression formula for f_n (N, n) in terms of the named input columns (each (N,)) over the terms of
    ``library`` (``velocities``, ``time``: the inputs that are velocities, time): a :class:`Law` of status "hint"
    (``n_terms``: nonzero library terms over all components)."""
    from nnphd._extras import require

    STLSQ = require("pysindy", "the sparse (blind) explanation").STLSQ

    names, x, y = regression_data(inputs, fn, component_names)
    vel_idx = [names.index(v) for v in velocities]
    t_idx = names.index(time) if time is not None else None
    theta, terms = _library(x, names, vel_idx, t_idx, library)
    scale = float(np.sqrt(np.mean(y**2))) or 1.0
    ys = y / scale
    m = ys.size
    if thresholds is None:
        thresholds = np.geomspace(1e-3, 1.0, 31)
    col_rms = np.sqrt(np.mean(theta**2, axis=0))
    col_rms = np.where(col_rms > 0, col_rms, 1.0)
    theta_n = theta / col_rms  # unit-rms columns: a threshold is a fraction of f_n's rms per unit-rms term
    # STLSQ's least-squares problems on Θ = QR are those on R with Qᵀy (‖Θc − y‖² = ‖Rc − Qᵀy‖² + a constant, for
    # every subset of columns): the same coefficients from a (terms × terms) system instead of one with a row per
    # sample — the path of a 4400-row double pendulum took 6 s, most of the blind formula's time
    Q, R = np.linalg.qr(theta_n)
    exprs, coefs = [], []
    for i in range(y.shape[1]):  # each component gets its own sparsity path
        yi = ys[:, i]
        zi = Q.T @ yi
        fits = [(0, float(np.sqrt(np.mean(yi**2))), np.zeros(theta.shape[1]))]  # (k, rel_rms, coef)
        for thr in thresholds:
            opt = STLSQ(threshold=float(thr), alpha=1e-10, max_iter=50)
            with warnings.catch_warnings():  # "eliminated all coefficients" is an expected end of the path
                warnings.simplefilter("ignore")
                opt.fit(R, zi[:, None])
            c = np.asarray(opt.coef_).reshape(-1) / col_rms
            fits.append((int(np.count_nonzero(c)), float(np.sqrt(np.mean((theta @ c - yi) ** 2))), c))
        fits += _best_small_subsets(theta_n, yi, col_rms)
        # parsimony: minimise log(rms) + term_cost·(terms), i.e. a term must cut the residual by a factor e^term_cost
        # (25% by default). In-sample BIC keeps adding collinear terms that fit the learned f_n's own errors.
        _, _, c = min(fits, key=lambda f: (np.log(max(f[1], 1e-12)) + term_cost * f[0], f[0]))
        coefs.append(c)
        exprs.append(sum((sp.Float(v * scale, 6) * term for v, term in zip(c, terms) if v != 0), sp.Integer(0)))
    coef = np.stack(coefs)
    k = int(np.count_nonzero(coef))
    rss = float(np.sum((theta @ coef.T - ys) ** 2))
    rel = float(np.sqrt(rss / m))
    readable = bool(rel <= READABLE_MAX_REL_RMS and 0 < k <= READABLE_MAX_TERMS)
    if readable:
        note = f"{k} terms explain f_n to {100 * rel:.1f}% rms"
    elif k == 0:
        note = "nothing readable: the sparsest model is zero"
    else:
        note = (
            f"nothing readable: the best sparse model needs {k} terms and leaves {100 * rel:.0f}% rms "
            f"(readable means ≤ {READABLE_MAX_TERMS} terms and ≤ {100 * READABLE_MAX_REL_RMS:.0f}%)"
        )
    return blind_law(SPARSE, exprs, component_names, rel, k, readable, note)
