r"""The ranked law table: one :class:`Candidate` per candidate family, the :class:`LawTable`, and how the winner is
chosen. A candidate is working state (arrays, mutable); its result is a :class:`~nnphd.explain.law.Law`
(:meth:`Candidate.to_law`, :meth:`LawTable.to_law`).

Candidates are ranked by

    IC = N_eff · log(held-out MSE) + k · log(N_eff),    N_eff = (rows × coordinates) / τ,

k the number of law parameters (τ and N_eff shrunk by the overdispersion ĉ, :func:`overdispersion_c_hat`); the zero law (f_c
alone) is a candidate too. A candidate with a term within :data:`Z_TERM` standard errors of zero, a nonlinear
parameter at the edge of its range or within :data:`Z_TERM` standard errors of a value that makes it a simpler
family in the table (:data:`SPECIAL_VALUES`: a power law's m = 0 or ½), a size at the rounding level of the data, (a
sum of terms) a term carrying
less than :data:`MIN_TERM_SHARE` of the law's force, or a drive whose force over the record is a force of the state
(R² ≥ :data:`DRIVE_STATE_R2` against 1, q, q̇, or a frequency within half a beat of the motion's over the record:
phase-locked to the motion, e.g. a few periods of a free decay) is not eligible. The winner is the
lowest IC; among the candidates within :data:`IC_TIE` of it that are special cases of it (:func:`nested`: no law, a
subset of its terms) the one with the fewest parameters. Other families within :data:`IC_TIE` that are not special
cases of the winner, nor it of them, are a tie
(:attr:`LawTable.ties`, :attr:`LawTable.status` "tie"): the record cannot tell them apart, no family is claimed
and all are reported with their coefficients. When no candidate beats zero, there is no law and the table says so
(:attr:`LawTable.reason`). Tables ranked on one record beside different conservative bases (a seed's LNN, the
seed-free conservative library) are combined by :func:`combine_bases`: a family is claimed only where they agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import sympy as sp

from nnphd.explain.families import DIGITS, Family
from nnphd.explain.law import FittedFamily, Law, LawStatus, TableStatus

__all__ = ["IC_TIE", "Z_TERM", "Candidate", "LawTable"]

IC_TIE = 6.0  # candidates within this IC of the best count as equally good: the simplest wins (ΔIC < 6: no strong preference)
Z_TERM = 2.0  # a term whose coefficient is within Z_TERM standard errors of zero makes its candidate ineligible
C_HAT_MAX = 20.0  # at most this overdispersion ĉ
DRIVE_STATE_R2 = 0.9  # a drive whose force is this much a force of the state (1, q, q̇) is not eligible
MIN_TERM_SHARE = 0.05  # a term of a sum that carries less than this share of the law's rms force is not needed:
# statistically "significant" on long clean records (it soaks up the smoothing of sign(q̇), the shape of the
# potential), physically negligible — the law without it is the answer


@dataclass
class Candidate:
    """One candidate of the ranking (internal working state: mutable, with the arrays the ranking needs); one row of
    the ranked table, :meth:`to_dict` as report.json writes it. Its result is a :class:`~nnphd.explain.law.Law`,
    via :meth:`to_law`."""

    key: str
    title: str
    k: int  # law parameters (the complexity)
    params: dict[str, float]
    stderr: dict[str, float]
    formula: dict[str, str]  # component name → SymPy string
    latex: dict[str, str]
    heldout_mse: float  # weighted held-out mean squared residual of the joint fit
    heldout_ratio: float  # held-out rms / the zero law's
    ic: float
    delta_ic: float  # IC − IC of the zero law (negative: better than no law)
    fn_rel: float  # rms of the law on the data / rms of q̈
    terms: tuple[str, ...]
    method: str = "pointwise"
    significant: bool = True  # every term's coefficient is ≥ Z_TERM standard errors from zero
    shares: dict[str, float] = field(default_factory=dict)  # each coefficient's rms force / the law's rms force
    state_like: float = 0.0  # a drive: R² of its force against (1, q, q̇) over the record (1: phase-locked)
    fn: np.ndarray | None = field(default=None, repr=False)  # the law on the data rows (N, n)
    family: Family | None = field(default=None, repr=False)
    theta: np.ndarray | None = field(default=None, repr=False)
    beta: np.ndarray | None = field(default=None, repr=False)
    cov: np.ndarray | None = field(default=None, repr=False)  # the coefficients' covariance (trajectory level)
    envelope: dict | None = (
        None  # its fit to the amplitude envelope: params, stderr, agree, distance2, delta_ic, windows
    )
    # the conservative coefficients of its joint trajectory-level fit and their covariance (τ-widened)
    conservative: np.ndarray | None = field(default=None, repr=False)
    conservative_cov: np.ndarray | None = field(default=None, repr=False)
    stuck: dict | None = None  # a stuck phase it cannot explain (:mod:`nnphd.explain.stuck`)

    def to_dict(self) -> dict:
        return {
            "law": self.key,
            "title": self.title,
            "k": self.k,
            "params": self.params,
            "stderr": self.stderr,
            "formula": self.formula,
            "latex": self.latex,
            "heldout_mse": self.heldout_mse,
            "heldout_ratio": self.heldout_ratio,
            "ic": self.ic,
            "delta_ic": self.delta_ic,
            "fn_rel": self.fn_rel,
            "terms": list(self.terms),
            "method": self.method,
            "significant": self.significant,
            "shares": self.shares,
            "state_like": self.state_like,
            **({"envelope": self.envelope} if self.envelope is not None else {}),
            **({"stuck": self.stuck} if self.stuck is not None else {}),
        }

    def to_law(
        self, status: LawStatus = LawStatus.CANDIDATE, table: tuple[dict, ...] = (), ties: tuple[dict, ...] = ()
    ) -> Law:
        """This candidate as a :class:`Law` of ``status`` (:class:`~nnphd.explain.law.LawStatus`: claimed, tie or
        candidate), with the ``table`` and ``ties`` it was ranked in (rows as :meth:`to_dict` writes them) — the Law
        that :meth:`Law.from_report <nnphd.explain.law.Law.from_report>` reads back from report.json."""
        return Law(
            self.key,
            self.title,
            dict(self.formula),
            dict(self.latex),
            dict(self.params),
            dict(self.stderr),
            self.method,
            tuple(table),
            status=status,
            ties=tuple(ties),
            fitted=self.fitted_family(),
        )

    def on_rows(self, q, qd, t) -> None:
        """Set :attr:`fn` (the law on the rows) and :attr:`shares` (each term's rms force over the law's)."""
        self.fn = self.predict(q, qd, t)
        if self.family is None:
            return
        q, qd, t = (np.asarray(a, float) for a in (q, qd, t))
        B = self.family.basis(np, self.theta, q, qd, t) * self.beta[None, None, :]
        total = float(np.sqrt(np.mean(self.fn**2)))
        rms = np.sqrt(np.mean(B**2, axis=(0, 1)))
        self.shares = {p: float(x / total) if total > 0 else 0.0 for p, x in zip(self.family.coef_names, rms)}
        if self.family.key == "drive":
            self.state_like = max(_state_r2(self.fn, q, qd), phase_locked(float(self.theta[0]), qd, t))

    def fitted_family(self) -> FittedFamily | None:
        """Its family with the fitted β and θ (None for the zero law)."""
        return None if self.family is None else FittedFamily(self.family, np.array(self.beta), np.array(self.theta))

    def predict(self, q, qd, t, xp=np):
        """The law at new states (N, n); ``xp`` numpy, or jax.numpy to trace it (e.g. inside an integrator)."""
        if self.family is None:
            return xp.zeros_like(xp.asarray(q, dtype=float))
        return self.fitted_family().predict(q, qd, t, xp)


@dataclass(frozen=True)
class BaseFit:
    """What the later stages of the law search start from, kept beside the table (not in its report): the pointwise
    joint fit's conservative coefficients (one vector per candidate, the zero law first), the centring of the
    library's columns, and the RMS of the fitted q̈ (the scale of the relative errors)."""

    alphas: list
    center: tuple | None
    y_rms: float


@dataclass
class LawTable:
    """The ranked candidates (winner first), the law (None when no candidate beats zero) and why. ``base``: the
    pointwise fit the later stages start from; ``whole_record``: what a tie's fit over the whole record needs
    (:func:`nnphd.explain.wholerecord.context`), on the table of the conservative library alone."""

    rows: list[Candidate]
    law: Candidate | None
    reason: str
    n_eff: float
    tau: float
    folds: str
    settings: dict
    ties: list[Candidate] = field(default_factory=list)  # families as good as the law (within IC_TIE, not nested)
    # no law because the best candidate's two fits (windows, envelope) disagree: that candidate (see envelope.py)
    blocked: Candidate | None = None
    base: BaseFit | None = None
    whole_record: dict | None = None

    @property
    def status(self) -> TableStatus:
        """ "claimed" (one family, the others clearly worse), "tie" (the record cannot tell :attr:`law` from
        :attr:`ties`: no family is claimed) or "none" (no candidate beats zero): a
        :class:`~nnphd.explain.law.TableStatus`."""
        if self.law is None:
            return TableStatus.NONE
        return TableStatus.TIE if self.ties else TableStatus.CLAIMED

    def to_law(self) -> Law | None:
        """The table's result: its law (status "claimed" or "tie", with the candidates and ties as report.json writes
        them), None when no candidate beats zero."""
        if self.law is None:
            return None
        rows = tuple(r.to_dict() for r in self.rows)
        return self.law.to_law(LawStatus(self.status), rows, tuple(r.to_dict() for r in self.ties))

    def to_dict(self) -> dict:
        return {
            "law": self.law.to_dict() if self.law else None,
            "status": self.status,
            "ties": [r.to_dict() for r in self.ties],
            "blocked_by": self.blocked.key if self.blocked is not None else None,
            "reason": self.reason,
            "candidates": [r.to_dict() for r in self.rows],
            "n_eff": self.n_eff,
            "tau": self.tau,
            "folds": self.folds,
            "settings": dict(self.settings),
        }


def overdispersion_ratio(se_boot, se_model, values=None) -> float | None:
    """Mean (bootstrap se / model se)² over a candidate's law parameters, at most C_HAT_MAX (None without any, or
    when the model error is at rounding level: exact data carry no information about overdispersion)."""
    scale = np.abs(values) if values is not None else np.zeros_like(se_model)
    ok = np.isfinite(se_boot) & np.isfinite(se_model) & (se_model > 1e-9 * scale) & (se_model > 0)
    return float(min(C_HAT_MAX, np.mean((se_boot[ok] / se_model[ok]) ** 2))) if ok.any() else None


def overdispersion_c_hat(ratios, errors) -> float:
    """Overdispersion ĉ ≥ 1 (as in QAIC, from the best-fitting model): (bootstrap / model variance) of the
    candidate with the lowest held-out error — when the resampled fits scatter more than the residuals' own scatter
    implies (misfit that varies along the record), the information in the data is smaller than its row count says,
    and every IC difference shrinks by ĉ."""
    ok = [(e, x) for x, e in zip(ratios, errors) if x is not None and np.isfinite(x)]
    return float(max(1.0, min(ok)[1])) if ok else 1.0


def at_bound(fam: Family, theta) -> bool:
    """A nonlinear parameter on (or past) a finite edge of its range: the optimum is not interior, the law is not
    identified (e.g. a power law pushed to m = 8 to fit a few of the fastest rows)."""
    if not fam.nl_names or theta is None or len(theta) == 0:
        return False
    lo, hi = (np.asarray(x, float) for x in fam.nl_bounds)
    th = np.asarray(theta, float)
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    tol = 1e-6 * np.maximum(span, 1e-12)
    return bool(np.any((np.isfinite(lo) & (th <= lo + tol)) | (np.isfinite(hi) & (th >= hi - tol))))


def _state_r2(fn: np.ndarray, q: np.ndarray, qd: np.ndarray) -> float:
    """R² of a time-dependent force against a force of the state, (1, q_i, q̇_i) per coordinate i, over the rows:
    a drive phase-locked to the motion (at its own frequency over a few periods, or in a steady state) is a friction
    or spring force in disguise — the record cannot tell it from one."""
    res = tot = 0.0
    for i in range(fn.shape[1]):
        X = np.stack([np.ones(len(q)), q[:, i] - q[:, i].mean(), qd[:, i]], axis=1)
        y = fn[:, i]
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        res += float(np.sum((y - X @ beta) ** 2))
        tot += float(np.sum((y - y.mean()) ** 2))
    return 1.0 - res / tot if tot > 0 else 1.0


def phase_locked(omega: float, qd: np.ndarray, t: np.ndarray) -> float:
    """1.0 when a drive at angular frequency ``omega`` stays within half a beat of the motion's own frequency (from
    the mean crossings of each velocity) over the record — over a free decay of a few periods a drive in phase with
    q̇ is a damping force in disguise (it fitted a servo's free drop better than any friction law) — else 0.0."""
    span = float(np.ptp(t)) if len(t) > 1 else 0.0
    if span <= 0:
        return 0.0
    for j in range(qd.shape[1]):
        y = qd[:, j] - qd[:, j].mean()
        i = np.flatnonzero(np.sign(y[1:]) * np.sign(y[:-1]) < 0)
        if len(i) < 2:
            continue
        w = np.pi * (len(i) - 1) / float(t[i[-1]] - t[i[0]]) if t[i[-1]] > t[i[0]] else np.inf
        if abs(abs(omega) - w) * span < np.pi:
            return 1.0
    return 0.0


# a nonlinear family's parameter values at which it is a simpler family (NESTS): the power law −k(|q̇|²)^m q̇ is
# viscous at m = 0 and quadratic drag at m = ½ (isotropic in 2-D, as both of those)
SPECIAL_VALUES = {"power": ("m", ((0.0, "linear"), (0.5, "quadratic")))}


def _at_special_value(r: Candidate, keys: set) -> bool:
    """Whether ``r``'s nonlinear parameter is within :data:`Z_TERM` standard errors of a value that makes it a
    simpler family ranked beside it (:data:`SPECIAL_VALUES`) — its extra parameter is not needed, as a term within
    Z_TERM standard errors of zero is not: the simpler family is the law. (The 2-D quadratic drag of the law table,
    beside an LNN, was claimed as a power law m = 0.476 ± 0.017, ΔIC > 6 ahead of quadratic drag.)"""
    name, specials = SPECIAL_VALUES.get(r.key, (None, ()))
    if name is None or name not in r.params:
        return False
    m, se = r.params[name], r.stderr.get(name, 0.0)
    return any(abs(m - v) < Z_TERM * se and key in keys for v, key in specials) if se > 0 else False


def _significance(rows: list[Candidate]) -> None:
    keys = {r.key for r in rows}
    for r in rows:
        if _at_special_value(r, keys):
            r.significant = False
            continue
        if r.family is not None and r.state_like >= DRIVE_STATE_R2:
            r.significant = False
            continue
        if r.family is not None and r.fn_rel < 1e-9:  # a law at the rounding level of the data is no law
            r.significant = False
            continue
        if r.family is not None and at_bound(r.family, r.theta):
            r.significant = False
            continue
        if r.family is not None and not dissipative_ok(r.family, r.beta):
            r.significant = False
            continue
        if r.family is not None and r.family.per_term:
            z = [abs(r.params[p]) / r.stderr[p] if r.stderr[p] > 0 else np.inf for p in r.family.coef_names]
            r.significant = bool(min(z) >= Z_TERM) if z else True
            if r.significant and len(r.family.terms) > 1 and r.shares:
                r.significant = min(r.shares.values()) >= MIN_TERM_SHARE


def dissipative_ok(fam: Family, beta) -> bool:
    """A sum of friction terms (viscous, dry, quadratic) is a friction law only with every coefficient ≥ 0: one
    negative term pumps energy in where the others take it out — a curve fitted to the record, not a mechanism
    (self-excitation has its own families, Rayleigh and van der Pol)."""
    return not fam.dissipative or bool(np.all(np.asarray(beta, float) >= 0))


def fitted_law(fitted: FittedFamily, names, status: LawStatus = LawStatus.CLAIMED) -> Law:
    """The :class:`Law` of a family with fitted coefficients and no table behind it (a model file holding a law its
    report does not name): the formula in the coordinates' ``names`` and the parameters; standard errors unknown
    (NaN); method "model file"."""
    se = np.full(fitted.family.k, np.nan)
    return law_row(fitted.family, fitted.beta, fitted.theta, se, names, float("nan"), "model file").to_law(status)


def law_row(fam: Family, beta, theta, se, names, heldout_mse: float, method: str) -> Candidate:
    """A table row: parameters ± se and the law as SymPy/LaTeX in the coordinates' names (IC set by the caller)."""
    Q = [sp.Symbol(c) for c in names]
    V = [sp.Symbol(f"{c}_dot") for c in names]
    sym = fam.symbols(theta, Q, V, sp.Symbol("t"))
    exprs = []
    for i in range(len(names)):
        e = sum((sp.Float(b, DIGITS) * s_ for b, s_ in zip(beta, sym[i]) if b != 0), sp.Integer(0))
        if fam.fixed is not None:
            e = e + sp.Symbol("(fixed part)")
        exprs.append(e)
    pn = list(fam.coef_names) + list(fam.nl_names)
    vals = np.concatenate([beta, theta])
    return Candidate(
        fam.key,
        fam.title,
        fam.k,
        {p: float(x) for p, x in zip(pn, vals)},
        {p: float(x) for p, x in zip(pn, se)},
        {f"{c}_ddot": str(e) for c, e in zip(names, exprs)},
        {f"{c}_ddot": sp.latex(e) for c, e in zip(names, exprs)},
        heldout_mse,
        1.0,
        0.0,
        0.0,
        0.0,
        fam.terms,
        method=method,
        family=fam,
        theta=np.asarray(theta, float),
        beta=np.asarray(beta, float),
    )


def zero_row(names, heldout_mse: float, N: int, method: str) -> Candidate:
    zero = {f"{c}_ddot": "0" for c in names}
    return Candidate(
        "none",
        "no law (conservative model alone)",
        0,
        {},
        {},
        zero,
        dict(zero),
        heldout_mse,
        1.0,
        0.0,
        0.0,
        0.0,
        (),
        method=method,
        fn=np.zeros((N, len(names))),
    )


def relative_to_zero(rows: list[Candidate], y_rms: float) -> None:
    """Held-out ratio and ΔIC against the zero law (rows[0]), and the law's size relative to q̈."""
    z = rows[0]
    for r in rows:
        r.heldout_ratio = float(math.sqrt(r.heldout_mse / z.heldout_mse)) if z.heldout_mse > 0 else 1.0
        r.delta_ic = r.ic - z.ic
        r.fn_rel = float(np.sqrt(np.mean(r.fn**2))) / (y_rms or 1.0)


def select_law(rows: list[Candidate], n_eff, tau, folds, settings, judge: bool = True, base=None) -> LawTable:
    if judge:
        _significance(rows)
    order = {id(r): i for i, r in enumerate(rows)}
    rows = sorted(rows, key=lambda r: r.ic)
    eligible = [r for r in rows if r.significant]
    best = eligible[0]
    tied = [r for r in eligible if r.ic <= best.ic + IC_TIE]
    # parsimony within the margin: the simplest candidate that is a special case of the best (no law, a term of a
    # sum, linear or quadratic drag of the power law) — a simpler family that is *not* one is a rival, not a winner
    # (a servo look-alike's viscous + dry law lost to "quadratic drag" this way, 72 % off)
    simpler = [r for r in tied if nested(r, best)]
    win = min(simpler, key=lambda r: (r.k, r.key == "sparse", r.ic, order[id(r)]))
    rows.remove(win)
    rows.insert(0, win)
    ties: list[Candidate] = []
    if win.key == "none":
        nxt = rows[1] if len(rows) > 1 else None
        reason = "no candidate beats zero: " + (
            f"the best, {nxt.title}, changes the held-out error by {100 * (nxt.heldout_ratio - 1):+.2f}% and its "
            f"{nxt.k} parameter(s) cost more (ΔIC = {nxt.delta_ic:+.1f})"
            if nxt and nxt.delta_ic >= 0
            else f"the best, {nxt.title} (ΔIC = {nxt.delta_ic:+.1f}), is not eligible — {INELIGIBLE}"
            if nxt
            else "no candidate could be fitted"
        )
        law = None
    else:
        reason = (
            f"{win.title} lowers the held-out error by {100 * (1 - win.heldout_ratio):.2f}% with {win.k} "
            f"parameter(s) (ΔIC = {win.delta_ic:.1f} against no law)"
        )
        ties = [
            r
            for r in tied
            if r is not win and r.key not in (win.key, "sparse") and not nested(win, r) and not nested(r, win)
        ]
        if ties:
            reason = _tie_reason(win, ties)
            rows = [win, *ties, *(r for r in rows[1:] if r not in ties)]  # the tied families first
        elif len(tied) > 1:
            reason += f"; {len(tied) - 1} other candidate(s) within ΔIC {IC_TIE:g} — the simplest is kept"
        skipped = [r for r in rows if not r.significant and r.ic < win.ic]
        if skipped:
            reason += (
                f"; {len(skipped)} candidate(s) with a lower IC are not eligible ({', '.join(r.key for r in skipped)}):"
                f" {INELIGIBLE}"
            )
        law = win
    return LawTable(rows, law, reason, float(n_eff), float(tau), folds, settings, ties, base=base)


INELIGIBLE = (
    f"a term within {Z_TERM:g} standard errors of zero or carrying < {100 * MIN_TERM_SHARE:g}% of the law's force, "
    f"a parameter at the edge of its range, a power law's exponent within {Z_TERM:g} standard errors of viscous "
    "(m = 0) or quadratic drag (m = ½), a sum of friction terms with a negative one, (a drive) a force "
    "phase-locked to the motion, or (with the amplitude envelope) its windows' and envelope's coefficients "
    "disagree or its windows reject it"
)

# families a nonlinear family holds as special cases (the power law: viscous at m = 0, quadratic drag at ½)
NESTS = {key: tuple(fam for _, fam in specials) for key, (_, specials) in SPECIAL_VALUES.items()}


def nested(a: Candidate, b: Candidate) -> bool:
    """Whether ``a`` is a special case of ``b``: the same, no law, its terms a subset of b's, or listed in NESTS."""
    if a is b or a.key == "none" or a.key == b.key:
        return True
    if b.key == "none" or "sparse" in (a.key, b.key):
        return False
    return set(a.terms) <= set(b.terms) or a.key in NESTS.get(b.key, ())


def _coefs(r: Candidate) -> str:
    return ", ".join(f"{p} = {v:.3g} ± {r.stderr.get(p, float('nan')):.2g}" for p, v in r.params.items())


def _tie_reason(win: Candidate, ties: list[Candidate]) -> str:
    """The words of a tie: the families, their coefficients and how close they are."""
    gap = max(abs(r.ic - win.ic) for r in ties)
    names = " or ".join([win.title, *(r.title for r in ties)])
    return (
        f"{names}: this record cannot tell them apart (ΔIC {gap:.1f} < {IC_TIE:g}; neither is a special case of the "
        "other); "
        f"no family is claimed, all are shown — {win.key}: {_coefs(win)}; "
        + "; ".join(f"{r.key}: {_coefs(r)}" for r in ties)
        + f" (the first, {win.key}, is used for predictions)"
    )


def preferred(table: LawTable) -> list[Candidate]:
    """The families a table points to: its law and its ties; without a law, the candidate that bars one (its two
    fits disagree, :attr:`LawTable.blocked`); else none."""
    if table.law is not None:
        return [table.law, *table.ties]
    return [table.blocked] if table.blocked is not None else []


def combine_bases(tables: list[tuple[str, LawTable]]) -> LawTable:
    """One law from tables ranked on the same record with different conservative bases (e.g. the seed-independent
    conservative library and a seed's LNN): a family is claimed only when every base that points to a family
    (:func:`preferred`) points to that one and one base claims it — the first such base's fit is kept; where they
    point to different families, those families tie (the record cannot tell them apart without knowing the
    conservative force better; the first eligible one is used for predictions); a base that finds no candidate at
    all does not veto. ``tables[0]`` gives the rows when no base points anywhere. Each base's view is in
    ``settings["bases"]``."""
    views = [(name, t, preferred(t)) for name, t in tables]
    summary = [
        {
            "base": name,
            "status": t.status if t.blocked is None else "blocked",
            "families": [r.key for r in p],
            "law": t.law.to_dict() if t.law is not None else None,
            "reason": t.reason,
            **({"funnel": t.settings["funnel"]} if "funnel" in t.settings else {}),  # how many families it fitted
        }
        for name, t, p in views
    ]
    keys: list[str] = []
    for _, _, p in views:
        keys += [r.key for r in p if r.key not in keys]
    says = "; ".join(f"with {s['base']}: {', '.join(s['families']) or 'no family'} ({s['status']})" for s in summary)
    if not keys:
        t = tables[0][1]
        return replace(t, settings={**t.settings, "bases": summary}, reason=t.reason + f" [{says}]")

    def fits(key):  # the eligible fits of a family, in the order of the bases, then the barred ones
        rs = [r for _, _, p in views for r in p if r.key == key]
        return sorted(rs, key=lambda r: not r.significant)

    shown = [fits(k)[0] for k in keys]
    claims = [r for r in shown if r.significant]
    home = next((t for _, t, p in views if any(r is shown[0] for r in p)), tables[0][1])
    settings = {**home.settings, "bases": summary}
    if not claims:  # every base that points anywhere points to a barred candidate
        t = next(t for _, t, p in views if p)
        return replace(t, settings=settings, reason=t.reason + f" [{says}]")
    law = claims[0]
    rows = [law, *(r for r in home.rows if r is not law)]
    if len(keys) == 1:
        return replace(home, rows=rows, law=law, ties=[], blocked=None, settings=settings,
                       reason=home.reason + f" [the same family {says}]")  # fmt: skip
    ties = [r for r in shown if r is not law]
    reason = (
        f"{' or '.join([law.title, *(r.title for r in ties)])}: the law depends on the conservative force it is "
        f"fitted beside ({says}) — no family is claimed, all are shown — "
        + "; ".join(f"{r.key}: {_coefs(r)}" for r in [law, *ties])
        + f" (the first, {law.key}, is used for predictions)"
    )
    return replace(home, rows=rows, law=law, ties=ties, blocked=None, settings=settings, reason=reason)
