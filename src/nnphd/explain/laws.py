r"""The law of the non-conservative force: candidate laws fitted *jointly* with a conservative model, ranked by
held-out error with a parsimony penalty, each with bootstrap uncertainties.

Model. q̈ = f_c(q, q̇) + g(q, q̇, t; β, θ), fitted to the rows (q, q̇, q̈, t) of the data:

* **f_c, the conservative part**, is linear in its coefficients α: a per-coordinate scale of a given conservative
  force (the LNN's f_c, or a feature Lagrangian's), plus a correction library that is even under time reversal
  (q̇ → −q̇), as every force from a Lagrangian T(q, q̇) − V(q) is — gradients of potential monomials in the
  positions up to degree 4 (angles enter as sin θ, cos θ; gradients, not free per-coordinate polynomials, because
  on an orbit the velocity is a rotation of the position and a curl field would absorb friction), the quadratic
  velocity terms q̇_j q̇_k (Christoffel-type) — and the one time-reversal-odd conservative force, the gyroscopic
  (magnetic-type) term B q̇ with B antisymmetric.
* **g, the candidate law**, is linear in β given a few nonlinear parameters θ (an exponent m, a drive frequency ω):
  every candidate is odd under time reversal (it does work) or explicitly time-dependent. Families
  (:func:`families`): linear friction (isotropic, diagonal, full Γ), quadratic drag −c|q̇|q̇, Coulomb −μ sign(q̇)
  (smoothed: q̇/√(q̇² + ε²), ε = 2 % of the rms speed), the power law −k(|q̇|²)^m q̇ with m free, Rayleigh (a + c q̇²)q̇,
  van der Pol (a + b q²)q̇ and both together, a drive A cos(ωt + φ) with ω started from the peaks of the conservative
  residual's Lomb–Scargle spectrum, a sparse polynomial (odd in q̇, degree ≤ 3, thresholded jointly with f_c), and
  user laws written as SymPy strings (:func:`parse_law`).

**Joint fit under the paper's principle.** For each candidate, (α, β) minimise Σ w²(q̈ − f_c − g)² + μ w̄² Σ g² with
μ = :data:`MU` (the paper's L_e + λ L_b with λ ≪ 1, in the 2-norm; w̄² the mean of w², so the penalty weighs f_n
alike in every coordinate, as the paper's L_b does): where the conservative model and the law can both
explain a piece of the data (a gyroscopic force is also the antisymmetric part of a full Γ), the conservative model
takes it and the law is the *minimal* non-conservative remainder. θ is found by variable projection (scipy
least_squares over θ, β and α solved linearly at each θ). Weights w are 1/(estimated q̈ error) per row and coordinate
where given, else 1/rms(q̈) per coordinate.

**Held-out error, uncertainty, selection.** The fit is linearised at its optimum (Jacobian J over α, β, θ); the data
are cut into folds — whole trajectories when there are ≥ 3, else :data:`N_FOLDS` contiguous stretches of each
trajectory — and each fold is predicted by the fit to the others (one Gauss–Newton step from the optimum: exact for
the linear families). Coefficient uncertainties are the spread of a moving-block bootstrap over the rows (blocks of 2τ
samples, τ the integrated autocorrelation time of the residuals: derivative errors are correlated over the
differentiation window), the larger of it and the model-based standard error inflated by √τ. Candidates are ranked by

    IC = N_eff · log(held-out MSE) + k · log(N_eff),    N_eff = (rows × coordinates) / τ,

k the number of law parameters; the zero law (f_c alone) is a candidate too. The winner is the lowest IC; among the
candidates within :data:`IC_TIE` of it the one with the fewest parameters (then the earlier, more specific family).
When no candidate beats zero, there is no law and the table says so (:attr:`LawTable.reason`).
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import sympy as sp

__all__ = [
    "IC_TIE",
    "MU",
    "N_FOLDS",
    "Family",
    "LawFit",
    "LawTable",
    "conservative_basis",
    "families",
    "family_from_spec",
    "parse_law",
    "perturber_family",
    "rank_laws",
]

MU = 1e-6  # weight of the minimal-f_n penalty (the paper's λ < 1; tiny: it only decides between exact ties)
IC_TIE = 6.0  # candidates within this IC of the best count as equally good: the simplest wins (ΔIC < 6: no strong preference)
N_FOLDS = 5  # held-out folds per trajectory when there are fewer than 3 trajectories
N_BOOT = 200
Z_TERM = 2.0  # a term whose coefficient is within Z_TERM standard errors of zero makes its candidate ineligible
COULOMB_EPS = 0.02  # smoothing of sign(q̇), as a fraction of the rms speed
SPARSE_DEGREE = 3
DIGITS = 4


# ---------------------------------------------------------------------------------------------------------- families
@dataclass(frozen=True, eq=False)
class Family:
    """A candidate law g = Σ_k β_k b_k(q, q̇, t; θ): ``basis(xp, θ, q, v, t)`` → (N, n, K) with xp numpy or jax.numpy;
    ``symbols(θ, Q, V, T)`` → n×K SymPy basis (Q, V lists of coordinate / velocity symbols, T time)."""

    key: str
    title: str
    coef_names: tuple[str, ...]
    basis: Callable
    symbols: Callable
    nl_names: tuple[str, ...] = ()
    nl_starts: Callable | None = None  # (ctx) -> list of start vectors θ0
    nl_bounds: tuple = ((), ())
    terms: tuple[str, ...] = ()  # structural labels, e.g. ("q̇",) — what "the form" of the law is
    fixed: Callable | None = None  # (xp, θ, q, v, t) -> (N, n): a parameter-free part of a user law
    per_term: bool = True  # each coefficient multiplies its own term (so each must be significant)
    spec: dict | None = None  # how to build it again (:func:`family_from_spec`): JSON-ready

    @property
    def k(self) -> int:
        return len(self.coef_names) + len(self.nl_names)


def _eye_cols(xp, cols):
    """(N, n) columns → (N, n, n) with column j in component j only."""
    n = cols.shape[1]
    return cols[:, :, None] * xp.eye(n, dtype=cols.dtype)[None]


def _sym_diag(n, per):
    """n×n SymPy matrix with per[i] on the diagonal."""
    return [[per[i] if i == j else sp.Integer(0) for j in range(n)] for i in range(n)]


def families(n: int, names: Sequence[str], v_rms: np.ndarray) -> list[Family]:
    """The built-in candidate families for n coordinates (names for the parameters; v_rms (n,) the rms speeds)."""
    eps = np.maximum(COULOMB_EPS * np.asarray(v_rms, float), 1e-12)
    eps_all = float(max(COULOMB_EPS * np.sqrt(np.sum(np.square(v_rms))), 1e-12))
    nm = list(names)
    out: list[Family] = []
    one = n == 1

    def add(*a, **kw):
        out.append(Family(*a, **kw))

    # linear friction
    if not one:
        add("linear", "linear friction −γ q̇ (isotropic)", ("gamma",),
            lambda xp, th, q, v, t: -v[:, :, None], lambda th, Q, V, T: [[-V[i]] for i in range(n)], terms=("q̇",))
    add("linear-diag" if not one else "linear", "linear friction −γ_i q̇_i" if not one else "linear friction −γ q̇",
        tuple(f"gamma_{c}" for c in nm) if not one else ("gamma",),
        lambda xp, th, q, v, t: _eye_cols(xp, -v), lambda th, Q, V, T: _sym_diag(n, [-x for x in V]),
        terms=("q̇_i",) if not one else ("q̇",))
    if not one:
        add("linear-full", "linear friction −Γ q̇ (full Γ)", tuple(f"Gamma_{a}{b}" for a in nm for b in nm),
            lambda xp, th, q, v, t: -(v[:, None, None, :] * xp.eye(n, dtype=v.dtype)[None, :, :, None]).reshape(
                v.shape[0], n, n * n),
            lambda th, Q, V, T: [[(-V[j] if a == i else sp.Integer(0)) for a in range(n) for j in range(n)]
                                 for i in range(n)], terms=("Γq̇",))
    # quadratic drag
    if not one:
        add("quadratic", "quadratic drag −c |q̇| q̇", ("c",),
            lambda xp, th, q, v, t: -(xp.sqrt(xp.sum(v * v, axis=1))[:, None] * v)[:, :, None],
            lambda th, Q, V, T: [[-sp.sqrt(sum(x**2 for x in V)) * V[i]] for i in range(n)], terms=("|q̇|q̇",))
    add("quadratic-diag" if not one else "quadratic", "quadratic drag −c_i |q̇_i| q̇_i" if not one else
        "quadratic drag −c |q̇| q̇", tuple(f"c_{c}" for c in nm) if not one else ("c",),
        lambda xp, th, q, v, t: _eye_cols(xp, -xp.abs(v) * v),
        lambda th, Q, V, T: _sym_diag(n, [-sp.Abs(x) * x for x in V]), terms=("|q̇_i|q̇_i",) if not one else ("|q̇|q̇",))
    # Coulomb (dry) friction, smoothed sign
    if not one:
        add("coulomb", "Coulomb friction −μ q̇/|q̇|", ("mu",),
            lambda xp, th, q, v, t: -(v / xp.sqrt(xp.sum(v * v, axis=1) + eps_all**2)[:, None])[:, :, None],
            lambda th, Q, V, T: [[-V[i] / sp.sqrt(sum(x**2 for x in V))] for i in range(n)], terms=("q̇/|q̇|",))
    add("coulomb-diag" if not one else "coulomb", "Coulomb friction −μ_i sign(q̇_i)" if not one else
        "Coulomb friction −μ sign(q̇)", tuple(f"mu_{c}" for c in nm) if not one else ("mu",),
        lambda xp, th, q, v, t: _eye_cols(xp, -v / xp.sqrt(v * v + xp.asarray(eps, v.dtype) ** 2)),
        lambda th, Q, V, T: _sym_diag(n, [-sp.sign(x) for x in V]), terms=("sign(q̇_i)",) if not one else ("sign(q̇)",))

    # power law with m free
    def _pow_basis(xp, th, q, v, t):
        s = xp.sum(v * v, axis=1)
        sm = xp.where(s > 0, xp.where(s > 0, s, 1.0) ** th[0], 0.0)
        return -(sm[:, None] * v)[:, :, None]

    add("power", "power-law drag −k (|q̇|²)^m q̇", ("k",), _pow_basis,
        lambda th, Q, V, T: [[-(sum(x**2 for x in V)) ** sp.Float(th[0], DIGITS) * V[i]] for i in range(n)],
        nl_names=("m",), nl_starts=lambda ctx: [[0.25], [1.0], [2.0], [4.0]], nl_bounds=([0.0], [8.0]),
        terms=("(|q̇|²)^m q̇",), per_term=False)
    # Rayleigh / van der Pol, per coordinate
    sfx = (lambda c: f"_{c}") if not one else (lambda c: "")
    add("rayleigh", "Rayleigh (a + c q̇²) q̇", tuple(f"{p}{sfx(c)}" for p in ("a", "c") for c in nm),
        lambda xp, th, q, v, t: xp.concatenate([_eye_cols(xp, v), _eye_cols(xp, v**3)], axis=2),
        lambda th, Q, V, T: [r1 + r2 for r1, r2 in zip(_sym_diag(n, V), _sym_diag(n, [x**3 for x in V]))],
        terms=("q̇", "q̇³"))
    add("vanderpol", "van der Pol (a + b q²) q̇", tuple(f"{p}{sfx(c)}" for p in ("a", "b") for c in nm),
        lambda xp, th, q, v, t: xp.concatenate([_eye_cols(xp, v), _eye_cols(xp, q * q * v)], axis=2),
        lambda th, Q, V, T: [r1 + r2 for r1, r2 in zip(_sym_diag(n, V), _sym_diag(n, [x**2 * y for x, y in zip(Q, V)]))],
        terms=("q̇", "q²q̇"))
    add("rayleigh-vdp", "Rayleigh–van der Pol (a + b q² + c q̇²) q̇",
        tuple(f"{p}{sfx(c)}" for p in ("a", "b", "c") for c in nm),
        lambda xp, th, q, v, t: xp.concatenate([_eye_cols(xp, v), _eye_cols(xp, q * q * v), _eye_cols(xp, v**3)],
                                               axis=2),
        lambda th, Q, V, T: [r1 + r2 + r3 for r1, r2, r3 in zip(_sym_diag(n, V),
                                                               _sym_diag(n, [x**2 * y for x, y in zip(Q, V)]),
                                                               _sym_diag(n, [x**3 for x in V]))],
        terms=("q̇", "q²q̇", "q̇³"))

    # drive of unknown frequency
    def _drive_basis(xp, th, q, v, t):
        c, s = xp.cos(th[0] * t), xp.sin(th[0] * t)
        ones = xp.ones_like(q)
        return xp.concatenate([_eye_cols(xp, c[:, None] * ones), _eye_cols(xp, s[:, None] * ones)], axis=2)

    add("drive", "drive A cos(ω t + φ)", tuple(f"{p}{sfx(c)}" for p in ("A_cos", "A_sin") for c in nm), _drive_basis,
        lambda th, Q, V, T: [r1 + r2 for r1, r2 in zip(_sym_diag(n, [sp.cos(sp.Float(th[0], 6) * T)] * n),
                                                       _sym_diag(n, [sp.sin(sp.Float(th[0], 6) * T)] * n))],
        nl_names=("omega",), nl_starts=lambda ctx: [[w] for w in ctx["drive_omegas"]],
        nl_bounds=([1e-9], [np.inf]), terms=("cos(ωt)",), per_term=False)
    spec = {"kind": "builtin", "v_rms": [float(x) for x in np.asarray(v_rms, float)]}
    return [replace(f, spec={**spec, "key": f.key}) for f in out]


def family_from_spec(spec: dict, names: Sequence[str]) -> Family:
    """The family a :attr:`Family.spec` describes, for the coordinates ``names`` (to load a saved law)."""
    names = list(names)
    kind = spec.get("kind")
    if kind == "builtin":
        for f in families(len(names), names, np.asarray(spec["v_rms"], float)):
            if f.key == spec["key"]:
                return f
        raise ValueError(f"no built-in law family {spec['key']!r} for {len(names)} coordinate(s)")
    if kind == "sparse":
        return sparse_family(len(names), names, np.asarray(spec["support"], bool))
    if kind == "user":
        return parse_law(spec["text"], names)
    if kind == "perturber":
        return perturber_family(names)
    raise ValueError(f"unknown law family spec {spec!r}; expected kind builtin, sparse, user or perturber")


def perturber_family(names: Sequence[str]) -> Family:
    """A point mass on a circular orbit, g = GM (r_p(t) − q)/|r_p(t) − q|³, r_p = R (cos(ωt + φ), sin(ωt + φ)) (n = 2;
    the paper's Neptune). GM is linear; R, ω, φ are started from :func:`nnphd.explain.parametric.fit_perturber`'s grid
    on the conservative residual (ctx["residual"]). Opt-in (``rank_laws(perturber=True)``): it only makes sense
    for orbits."""

    def _rp(xp, th, t):
        ang = th[1] * t + th[2]
        return th[0] * xp.stack([xp.cos(ang), xp.sin(ang)], axis=1)

    def basis(xp, th, q, v, t):
        d = _rp(xp, th, t) - q
        return (d / xp.sum(d * d, axis=1, keepdims=True) ** 1.5)[:, :, None]

    def symbols(th, Q, V, T):
        R, w, ph = (sp.Float(x, 6) for x in th)
        d = [R * sp.cos(w * T + ph) - Q[0], R * sp.sin(w * T + ph) - Q[1]]
        r3 = (d[0] ** 2 + d[1] ** 2) ** sp.Rational(3, 2)
        return [[d[0] / r3], [d[1] / r3]]

    def starts(ctx):
        from nnphd.explain.parametric import fit_perturber

        try:
            f = fit_perturber(ctx["q"], ctx["t"], ctx["residual"])
        except ValueError:
            return []
        return [[f.params["R"], f.params["omega"], f.params["phi"]]]

    return Family("perturber", "perturber GM (r_p(t) − q)/|r_p(t) − q|³ on a circular orbit", ("GM",), basis, symbols,
                  nl_names=("R", "omega", "phi"), nl_starts=starts,
                  nl_bounds=([1e-9, -np.inf, -np.inf], [np.inf, np.inf, np.inf]), terms=("(r_p(t) − q)/|r_p − q|³",),
                  per_term=False, spec={"kind": "perturber"})


def _odd_monomials(n: int, degree: int = SPARSE_DEGREE) -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    """Exponent pairs (of q, of q̇) of the monomials of total degree ≤ degree that are odd in q̇."""
    import itertools

    out = []
    for e in itertools.product(range(degree + 1), repeat=2 * n):
        if 0 < sum(e) <= degree and sum(e[n:]) % 2 == 1:
            out.append((tuple(e[:n]), tuple(e[n:])))
    out.sort(key=lambda m: (sum(m[0]) + sum(m[1]), m[1][::-1], m[0][::-1]))
    return out


def _monomial_cols(xp, mons, q, v):
    cols = []
    for eq, ev in mons:
        c = xp.ones_like(q[:, 0])
        for j, e in enumerate(eq):
            if e:
                c = c * q[:, j] ** e
        for j, e in enumerate(ev):
            if e:
                c = c * v[:, j] ** e
        cols.append(c)
    return xp.stack(cols, axis=1)


def _monomial_sym(mons, Q, V):
    return [sp.Mul(*[x**e for x, e in zip(Q, eq)], *[x**e for x, e in zip(V, ev)]) for eq, ev in mons]


def sparse_family(n: int, names: Sequence[str], support: np.ndarray) -> Family:
    """The sparse polynomial law restricted to ``support`` (n × M boolean over :func:`_odd_monomials`)."""
    mons = _odd_monomials(n)
    idx = [(i, m) for i in range(n) for m in range(len(mons)) if support[i, m]]

    def basis(xp, th, q, v, t):
        cols = _monomial_cols(xp, mons, q, v)  # (N, M)
        out = [cols[:, m][:, None] * xp.eye(n, dtype=q.dtype)[i][None] for i, m in idx]
        return xp.stack(out, axis=2) if out else xp.zeros((q.shape[0], n, 0), q.dtype)

    def symbols(th, Q, V, T):
        ms = _monomial_sym(mons, Q, V)
        return [[ms[m] if i == c else sp.Integer(0) for c, m in idx] for i in range(n)]

    Qs = [sp.Symbol(c) for c in names]
    Vs = [sp.Symbol(f"{c}_dot") for c in names]
    msym = _monomial_sym(mons, Qs, Vs)
    coef = tuple(f"{names[i]}_ddot:{msym[m]}" for i, m in idx)
    return Family("sparse", "sparse polynomial (odd in q̇, degree ≤ 3)", coef, basis, symbols,
                  terms=tuple(sorted({str(msym[m]) for _, m in idx})),
                  spec={"kind": "sparse", "support": np.asarray(support, bool).tolist()})


# ---------------------------------------------------------------------------------------------------------- user laws
_USER_SPLIT = re.compile(r"\s*;\s*")


def parse_law(text: str, coords: Sequence[str]) -> Family:
    """A user law from a SymPy string: ``"-c*x_dot*abs(x_dot)"`` (one coordinate) or ``"x: -c*x_dot; y: -c*y_dot"``.

    Symbols: the coordinate names, ``<name>_dot``, ``t``; every other symbol is a parameter (shared between
    components). Parameters the law is linear in are solved exactly, the rest (e.g. an exponent) by least squares
    from 1. Raises ValueError with a one-line message on a law that cannot be used.
    """
    coords = list(coords)
    text = str(text).strip()
    if not text:
        raise ValueError("--law is empty: expected a formula such as 'c*x_dot*abs(x_dot)'")
    parts = [p for p in _USER_SPLIT.split(text) if p]
    comps: dict[int, str] = {}
    for p in parts:
        head, sep, body = p.partition(":")
        if sep:
            name = head.strip().removesuffix("_ddot")
            if name not in coords:
                raise ValueError(f"law {text!r}: {head.strip()!r} is not a coordinate (expected one of "
                                 f"{', '.join(coords)})")
            comps[coords.index(name)] = body
        elif len(coords) == 1 and not comps:
            comps[0] = p
        else:
            raise ValueError(f"law {text!r}: with {len(coords)} coordinates name the component of each term, "
                             f"e.g. '{coords[0]}: -c*{coords[0]}_dot; {coords[1]}: -c*{coords[1]}_dot'")
    Q = [sp.Symbol(c) for c in coords]
    V = [sp.Symbol(f"{c}_dot") for c in coords]
    T = sp.Symbol("t")
    known = {s.name: s for s in (*Q, *V, T)}
    exprs = [sp.Integer(0)] * len(coords)
    for i, body in comps.items():
        try:
            e = sp.sympify(body, locals={**known, "abs": sp.Abs, "sign": sp.sign})
        except (sp.SympifyError, SyntaxError, TypeError) as err:
            raise ValueError(f"law {text!r}: cannot read {body.strip()!r} as a formula ({err.__class__.__name__})") \
                from None
        if not isinstance(e, sp.Expr):
            raise ValueError(f"law {text!r}: {body.strip()!r} is not a formula")  # noqa: TRY004 (a bad --law is bad input: exit 2)
        exprs[i] = e
    params = sorted({s for e in exprs for s in e.free_symbols} - set(known.values()), key=lambda s: s.name)
    if not params:
        raise ValueError(f"law {text!r} has no free parameter to fit (symbols other than the coordinates, "
                         f"their _dot velocities and t are parameters)")
    bad = [p.name for p in params if p.name.endswith("_dot")]
    if bad:
        raise ValueError(f"law {text!r}: {bad[0]!r} is not the velocity of a coordinate (coordinates: "
                         f"{', '.join(coords)})")
    lin: list = []  # parameters the law is jointly linear in (their coefficients may hold the others)
    for p in params:
        if all(sp.simplify(sp.diff(e, p, 2)) == 0 and all(sp.simplify(sp.diff(e, p, p2)) == 0 for p2 in lin)
               for e in exprs):
            lin.append(p)
    nl = [p for p in params if p not in lin]
    base = [[sp.diff(e, p) for p in lin] for e in exprs]
    rest = [sp.simplify(e - sum((p * b for p, b in zip(lin, row)), sp.Integer(0))) for e, row in zip(exprs, base)]
    args = (nl, Q, V, T)
    n = len(coords)

    def _fn(xp, exprs_):
        mod = "jax" if xp.__name__.startswith("jax") else "numpy"
        f = sp.lambdify(args, exprs_, modules=mod)

        def ev(th, q, v, t):
            vals = f(list(th), [q[:, j] for j in range(n)], [v[:, j] for j in range(n)], t)
            return [xp.broadcast_to(xp.asarray(x, dtype=q.dtype), t.shape) for x in vals]
        return ev

    flat = [b for row in base for b in row]
    cache: dict = {}

    def basis(xp, th, q, v, t):
        key = (xp.__name__, "b")
        if key not in cache:
            cache[key] = _fn(xp, flat)
        vals = cache[key](th, q, v, t)
        K = len(lin)
        cols = [xp.stack([vals[i * K + k] for i in range(n)], axis=1) for k in range(K)]
        return xp.stack(cols, axis=2) if cols else xp.zeros((q.shape[0], n, 0), q.dtype)

    fixed = None
    if any(r != 0 for r in rest):
        def fixed(xp, th, q, v, t):
            key = (xp.__name__, "f")
            if key not in cache:
                cache[key] = _fn(xp, rest)
            return xp.stack(cache[key](th, q, v, t), axis=1)

    def symbols(th, Qs, Vs, Ts):
        sub = {**{a: b for a, b in zip(Q, Qs)}, **{a: b for a, b in zip(V, Vs)}, T: Ts,
               **{p: sp.Float(x, DIGITS) for p, x in zip(nl, th)}}
        return [[b.xreplace(sub) for b in row] for row in base]

    fam = Family("user", f"user law {text}", tuple(p.name for p in lin), basis, symbols,
                 nl_names=tuple(p.name for p in nl), nl_starts=(lambda ctx: [[1.0] * len(nl)]) if nl else None,
                 nl_bounds=([-np.inf] * len(nl), [np.inf] * len(nl)), terms=(text,), fixed=fixed, per_term=False,
                 spec={"kind": "user", "text": text})
    if not lin:
        raise ValueError(f"law {text!r}: it must be linear in at least one parameter (a coefficient in front of a "
                         "term), e.g. 'c*x_dot**m'")
    _ = fam.symbols([1.0] * len(nl), Q, V, T)  # fail early on a formula SymPy cannot rebuild
    return fam


# ------------------------------------------------------------------------------------------------- conservative part
def _position_features(xp, q, angles, center=None):
    """sin θ, cos θ of angles; other coordinates centred and scaled by ``center`` = (mean, std) (n,) each.
    Returns (u (N, d), du (N, d), owner (d,)): the features, their derivatives along their coordinate, and which
    coordinate each belongs to."""
    feats, ders, owner = [], [], []
    for j in range(q.shape[1]):
        if angles[j]:
            s_, c_ = xp.sin(q[:, j]), xp.cos(q[:, j])
            feats += [s_, c_]
            ders += [c_, -s_]
            owner += [j, j]
        else:
            m, sd = (center[0][j], center[1][j]) if center is not None else (0.0, 1.0)
            feats.append((q[:, j] - m) / sd)
            ders.append(xp.ones_like(q[:, j]) / sd)
            owner.append(j)
    return xp.stack(feats, axis=1), xp.stack(ders, axis=1), owner


def _pot_monomials(d: int) -> list[tuple[int, ...]]:
    """Exponents of the potential monomials in d position features: degree 1…4 (1…3 beyond two features)."""
    import itertools

    deg = 4 if d <= 2 else 3
    return sorted((e for e in itertools.product(range(deg + 1), repeat=d) if 0 < sum(e) <= deg),
                  key=lambda e: (sum(e), e[::-1]))


def conservative_basis(xp, q, v, angles, fc=None, center=None, library: bool = True):
    """(N, n, Kc) columns of the conservative model (see the module docstring): per-coordinate scale of ``fc``
    (if given); gradients −∂V_e/∂q of potential monomials V_e in the position features (degree ≤ 4, ≤ 3 beyond two
    features; angles enter as sin θ, cos θ) — curl-free, so that no combination of them is a rotation field, which
    on an orbit would mimic friction (v ∝ a rotation of q); quadratic velocity terms; and the antisymmetric
    gyroscopic term (n ≥ 2). ``library=False``: the scale of ``fc`` alone (when ``fc`` comes from a trusted form,
    e.g. a system's feature Lagrangian)."""
    N, n = q.shape
    cols = []
    if fc is not None:
        cols.append(_eye_cols(xp, fc))
    if not library:
        if fc is None:
            raise ValueError("library=False needs a conservative force fc")
        return cols[0]
    u, du, owner = _position_features(xp, q, angles, center)
    d = u.shape[1]
    onehot = np.zeros((d, n))
    onehot[np.arange(d), owner] = 1.0
    onehot = xp.asarray(onehot, dtype=q.dtype)
    grads = []
    for e in _pot_monomials(d):
        parts = []
        for f in range(d):  # ∂V_e/∂u_f
            if e[f] == 0:
                parts.append(xp.zeros_like(q[:, 0]))
                continue
            c = e[f] * u[:, f] ** (e[f] - 1)
            for g, k in enumerate(e):
                if g != f and k:
                    c = c * u[:, g] ** k
            parts.append(c)
        dV = xp.stack(parts, axis=1) * du  # (N, d): ∂V/∂u_f · du_f/dq_owner(f)
        grads.append(dV @ onehot)  # (N, n)
    cols.append(xp.stack(grads, axis=2))
    pc = []
    for a in range(n):
        for b in range(a, n):
            pc.append(v[:, a] * v[:, b])
    P = xp.stack(pc, axis=1)  # (N, M)
    cols.append((P[:, None, :, None] * xp.eye(n, dtype=q.dtype)[None, :, None, :]).reshape(N, n, -1))
    if n >= 2:
        g = []
        for a in range(n):
            for b in range(a + 1, n):
                col = xp.zeros_like(q)
                col = col + v[:, b][:, None] * (xp.arange(n) == a)[None] - v[:, a][:, None] * (xp.arange(n) == b)[None]
                g.append(col)
        cols.append(xp.stack(g, axis=2))
    return xp.concatenate(cols, axis=2)


# ---------------------------------------------------------------------------------------------------------- results
@dataclass
class LawFit:
    """One fitted candidate (one row of the ranked table)."""

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
    fn: np.ndarray | None = field(default=None, repr=False)  # the law on the data rows (N, n)
    family: Family | None = field(default=None, repr=False)
    theta: np.ndarray | None = field(default=None, repr=False)
    beta: np.ndarray | None = field(default=None, repr=False)

    def to_dict(self) -> dict:
        return {"law": self.key, "title": self.title, "k": self.k, "params": self.params, "stderr": self.stderr,
                "formula": self.formula, "latex": self.latex, "heldout_mse": self.heldout_mse,
                "heldout_ratio": self.heldout_ratio, "ic": self.ic, "delta_ic": self.delta_ic,
                "fn_rel": self.fn_rel, "terms": list(self.terms), "method": self.method,
                "significant": self.significant}

    def predict(self, q, qd, t, xp=np):
        """The law at new states (N, n); ``xp`` numpy, or jax.numpy to trace it (e.g. inside an integrator)."""
        q, qd, t = (xp.asarray(a, dtype=float) for a in (q, qd, t))
        if self.family is None:
            return xp.zeros_like(q)
        theta = xp.asarray(self.theta)
        g = xp.einsum("snk,k->sn", self.family.basis(xp, theta, q, qd, t), xp.asarray(self.beta))
        if self.family.fixed is not None:
            g = g + self.family.fixed(xp, theta, q, qd, t)
        return g


@dataclass
class LawTable:
    """The ranked candidates (winner first), the law (None when no candidate beats zero) and why."""

    rows: list[LawFit]
    law: LawFit | None
    reason: str
    n_eff: float
    tau: float
    folds: str
    settings: dict

    def to_dict(self) -> dict:
        return {"law": self.law.to_dict() if self.law else None, "reason": self.reason,
                "candidates": [r.to_dict() for r in self.rows], "n_eff": self.n_eff, "tau": self.tau,
                "folds": self.folds, "settings": {k: v for k, v in self.settings.items() if not k.startswith("_")}}


# ---------------------------------------------------------------------------------------------------------- fitting
class _Problem:
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
                sol = least_squares(res, th0, bounds=(lo, hi), method="trf", x_scale="jac", xtol=1e-12,
                                    ftol=1e-12, max_nfev=200)
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
        J = np.concatenate([np.concatenate(cols, axis=1).reshape(self.N, self.n, -1),
                            np.concatenate(pcols, axis=1).reshape(self.N, self.n, -1)], axis=1)
        R = np.concatenate([fit["r"].reshape(self.N, self.n), fit["rp"].reshape(self.N, self.n)], axis=1)
        return J, R


def _solve(A, b):
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


def _ridge(G):
    return G + 1e-12 * max(float(np.trace(G)) / max(G.shape[0], 1), 1e-300) * np.eye(G.shape[0])


def _segments(traj) -> list[np.ndarray]:
    traj = np.asarray(traj)
    cuts = np.flatnonzero(np.diff(traj) != 0) + 1
    return np.split(np.arange(len(traj)), cuts)


def _folds(segs) -> tuple[list[np.ndarray], str]:
    if len(segs) >= 3:
        k = min(len(segs), 10)
        groups = np.array_split(np.arange(len(segs)), k)
        return [np.concatenate([segs[i] for i in g]) for g in groups], f"{k} folds of whole trajectories"
    folds = [np.concatenate(parts) for parts in zip(*[np.array_split(s, N_FOLDS) for s in segs])]
    return folds, f"{N_FOLDS} contiguous stretches of each trajectory"


def _tau(r: np.ndarray, segs) -> float:
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


def _linear_stats(J, R, folds, segs, tau, n_boot, seed, P_law_idx):
    """Held-out MSE by one Gauss–Newton step per fold, bootstrap and model covariance of the law parameters."""
    N, rows2, P = J.shape
    n = rows2 // 2
    Gs = np.einsum("sri,srj->sij", J, J)
    hs = np.einsum("sri,sr->si", J, R)
    G, h = Gs.sum(0), hs.sum(0)
    sse = 0.0
    m = 0
    for f in folds:
        Gf, hf = Gs[f].sum(0), hs[f].sum(0)
        d = _solve(_ridge(G - Gf), h - hf)
        pred = R[f, :n] - np.einsum("sri,i->sr", J[f, :n], d)
        sse += float(np.sum(pred**2))
        m += pred.size
    mse = sse / max(m, 1)
    # moving-block bootstrap over rows within trajectories
    L = max(1, math.ceil(2 * tau))
    blocks = [s[i:i + L] for s in segs for i in range(0, len(s), L)]
    Gb = np.stack([Gs[b].sum(0) for b in blocks])
    hb = np.stack([hs[b].sum(0) for b in blocks])
    rng = np.random.default_rng(seed)
    reps = []
    Gi = _ridge(G)
    for _ in range(n_boot):
        idx = rng.integers(0, len(blocks), len(blocks))
        reps.append(_solve(_ridge(Gb[idx].sum(0)), hb[idx].sum(0)))
    reps = np.asarray(reps)[:, P_law_idx] if len(P_law_idx) else np.zeros((n_boot, 0))
    se_boot = reps.std(axis=0) if n_boot > 1 else np.full(len(P_law_idx), np.inf)
    dof = max(N * n - P, 1)
    s2 = float(np.sum(R[:, :n] ** 2)) / dof
    cov = s2 * np.linalg.pinv(Gi)
    se_model = np.sqrt(np.maximum(np.diag(cov)[P_law_idx], 0.0) * tau) if len(P_law_idx) else np.zeros(0)
    return mse, se_boot, se_model


def _drive_omegas(t, r, segs, n_peaks: int = 3) -> list[float]:
    """Angular frequencies of the largest peaks of the residual's Lomb–Scargle spectrum (all components)."""
    from scipy.signal import lombscargle

    dts = np.concatenate([np.diff(t[s]) for s in segs if len(s) > 1])
    dt = float(np.median(dts[dts > 0])) if np.any(dts > 0) else 1.0
    span = float(np.max([np.ptp(t[s]) for s in segs]))
    if span <= 0:
        return [1.0]
    w = np.linspace(2 * np.pi / span, np.pi / dt, int(min(20000, max(200, 8 * span / dt))))
    P = np.zeros_like(w)
    for j in range(r.shape[1]):
        y = r[:, j] - r[:, j].mean()
        if np.any(y):
            P += lombscargle(t, y, w, normalize=False)
    peaks = [i for i in range(1, len(w) - 1) if P[i] >= P[i - 1] and P[i] >= P[i + 1]]
    peaks.sort(key=lambda i: -P[i])
    return [float(w[i]) for i in peaks[:n_peaks]] or [float(w[int(np.argmax(P))])]


def _sparse_supports(prob: _Problem, mons_n: int, n: int) -> list[np.ndarray]:
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


def rank_laws(q, qd, qdd, t, traj=None, *, names: Sequence[str] | None = None, angles=None, qdd_err=None,
              fc=None, user_laws: Sequence[str] = (), include: Sequence[str] | None = None, n_boot: int = N_BOOT,
              seed: int = 0, max_rows: int = 20000, library: bool = True,
              conservative_cols=None, perturber: bool = False) -> LawTable:
    """Fit every candidate law jointly with the conservative model and rank them (see the module docstring).

    q, qd, qdd (N, n); t (N,); traj (N,) trajectory ids (rows of a trajectory contiguous; None: one trajectory);
    names: coordinate names (default q1…); angles: n booleans; qdd_err (N, n) per-row q̈ errors (weights); fc (N, n) a
    conservative force to scale (e.g. the LNN's); user_laws: SymPy strings (:func:`parse_law`); include: family keys
    to try (default all but the opt-in ``"perturber"``); library: add the conservative correction library to the
    scale of fc (False: fc's scale alone — for a system's own feature Lagrangian). Rows beyond ``max_rows`` are
    thinned evenly. conservative_cols (N, n, K): more conservative columns, e.g. the derivatives ∂f_c/∂c of a feature
    Lagrangian's force by its coefficients, so that the joint fit re-fits c (linearised at the trained c); a table
    built with them is for the pointwise ranking only. perturber: add the perturber family (n = 2 orbits).
    """
    q, qd, qdd, t = (np.asarray(a, float) for a in (q, qd, qdd, t))
    if q.ndim != 2 or qd.shape != q.shape or qdd.shape != q.shape or t.shape != (q.shape[0],):
        raise ValueError(f"q, qd, qdd must be (N, n) and t (N,); got {q.shape}, {qd.shape}, {qdd.shape}, {t.shape}")
    N, n = q.shape
    names = list(names or [f"q{i + 1}" for i in range(n)])
    angles = np.zeros(n, bool) if angles is None else np.asarray(angles, bool)
    traj = np.zeros(N, int) if traj is None else np.asarray(traj)
    if qdd_err is not None:
        qdd_err = np.asarray(qdd_err, float)
        ok = np.isfinite(qdd_err) & (qdd_err > 0)
        fill = np.array([np.median(qdd_err[ok[:, j], j]) if ok[:, j].any() else np.std(qdd[:, j]) or 1.0
                         for j in range(n)])
        qdd_err = np.where(ok, qdd_err, fill[None])
        w = 1.0 / qdd_err
    else:
        w = np.broadcast_to(1.0 / np.maximum(np.sqrt(np.mean(qdd**2, axis=0)), 1e-300), (N, n)).copy()
    if N > max_rows:
        keep = np.unique(np.linspace(0, N - 1, max_rows).round().astype(int))
        q, qd, qdd, t, w, traj = q[keep], qd[keep], qdd[keep], t[keep], w[keep], traj[keep]
        fc = None if fc is None else np.asarray(fc, float)[keep]
        conservative_cols = None if conservative_cols is None else np.asarray(conservative_cols, float)[keep]
        N = len(keep)
    segs = _segments(traj)
    sd = q.std(axis=0)
    center = (q.mean(axis=0), np.where(sd > 0, sd, 1.0))  # positions enter the conservative library standardised
    C = conservative_basis(np, q, qd, angles, None if fc is None else np.asarray(fc, float), center, library)
    n_extra = 0
    if conservative_cols is not None:
        X = np.asarray(conservative_cols, float)
        if X.ndim != 3 or X.shape[:2] != (N, n) or not np.all(np.isfinite(X)):
            raise ValueError(f"conservative_cols must be finite and (N, n, K) = ({N}, {n}, K); got {X.shape}")
        C, n_extra = np.concatenate([C, X], axis=2), X.shape[2]
    prob = _Problem(q, qd, qdd, t, w, C, angles)
    folds, fold_desc = _folds(segs)
    v_rms = np.sqrt(np.mean(qd**2, axis=0))

    zero = prob.fit(None, {})
    r0 = zero["r"].reshape(N, n) / w
    ctx = {"drive_omegas": _drive_omegas(t, r0, segs), "q": q, "t": t, "residual": r0}
    fams = [f for f in families(n, names, v_rms) if include is None or f.key in include]
    if (perturber or (include is not None and "perturber" in include)) and n == 2:
        fams.append(perturber_family(names))
    if include is None or "sparse" in include:
        for sup in _sparse_supports(prob, len(_odd_monomials(n)), n):
            fams.append(sparse_family(n, names, sup))
    fams += [parse_law(u, names) for u in user_laws]

    fits = [(None, zero)]
    for f in fams:
        fit = prob.fit(f, ctx)
        if fit and np.all(np.isfinite(fit["r"])):
            fits.append((f, fit))
    # τ from the residuals of the best in-sample fit (the most signal removed), then held-out errors
    best_in = min(fits, key=lambda x: float(np.sum(x[1]["r"] ** 2)))
    tau = _tau(best_in[1]["r"].reshape(N, n), segs)
    n_eff = N * n / tau
    rows: list[LawFit] = []
    stats: list = []
    alphas: dict[int, np.ndarray] = {}
    Kc = prob.Z.shape[1]  # the Jacobian's conservative columns (reduced basis)
    for f, fit in fits:
        J, R = prob.jacobian(f, fit)
        law_idx = np.arange(Kc, J.shape[2])
        mse, se_b, se_m = _linear_stats(J, R, folds, segs, tau, n_boot if f is not None else 0, seed, law_idx)
        stats.append((mse, 0 if f is None else f.k,
                      _overdispersion(se_b, se_m, np.concatenate([fit["beta"], fit["theta"]]))))
        if f is None:
            row = _zero_row(names, mse, N, "pointwise")
        else:
            row = _law_row(f, fit["beta"], fit["theta"], np.maximum(se_b, se_m), names, mse, "pointwise")
            row.fn = row.predict(q, qd, t)
        rows.append(row)
        alphas[id(row)] = fit["alpha"]
    c_hat = _c_hat([x[2] for x in stats], [x[0] for x in stats])  # IC once the overdispersion is known
    n_eff = n_eff / c_hat
    tau = tau * c_hat
    for r, (mse, k, _) in zip(rows, stats):
        r.ic = n_eff * math.log(max(mse, 1e-300)) + k * math.log(max(n_eff, 2.0))
    y_rms = float(np.sqrt(np.mean(qdd**2)))
    _relative_to_zero(rows, y_rms)
    # the sparse family keeps only its best support
    sparse = [r for r in rows if r.key == "sparse"]
    if len(sparse) > 1:
        keep_s = min(sparse, key=lambda r: r.ic)
        rows = [r for r in rows if r.key != "sparse" or r is keep_s]
    named = {tuple(r.formula.values()) for r in rows if r.key != "sparse"}
    rows = [r for r in rows if r.key != "sparse" or tuple(r.formula.values()) not in named]
    settings = {"mu": MU, "ic_tie": IC_TIE, "n_boot": n_boot, "seed": seed, "rows": int(N), "method": "pointwise",
                "conservative_columns": int(C.shape[2]), "conservative_rank": int(Kc), "conservative_base": fc is not None, "names": names,
                "library": bool(library), "conservative_extra": int(n_extra), "_alpha": alphas, "_center": center, "_y_rms": y_rms}
    return _select(rows, n_eff, tau, fold_desc, settings)


# ------------------------------------------------------------------------------------------- trajectory-level ranking
def _universal_rhs(fams: Sequence[Family], Kc: int, angles: tuple, fc_fn, center, library: bool = True):
    """q̈ = f_c + Σ_families gate_f · g_f as one function of θ = (α, [β_f, θ_f, gate_f]…): every candidate is this
    model with the other families' gates at 0 — one compiled shooting function for all of them. The parameters
    actually fitted are u, with θ = base + u·D (``aux`` = (base, D))."""
    import jax.numpy as jnp

    sizes = [(len(f.coef_names), len(f.nl_names)) for f in fams]

    def rhs(u, q, v, t, aux):
        base, D = aux
        theta = base + u @ D
        fc = None if fc_fn is None else fc_fn(q, v)
        out = jnp.einsum("wnk,k->wn", conservative_basis(jnp, q, v, angles, fc, center, library), theta[:Kc])
        off = Kc
        for f, (K, m) in zip(fams, sizes):
            b, th, gate = theta[off:off + K], theta[off + K:off + K + m], theta[off + K + m]
            off += K + m + 1
            g = jnp.einsum("wnk,k->wn", f.basis(jnp, th, q, v, t), b)
            if f.fixed is not None:
                g = g + f.fixed(jnp, th, q, v, t)
            out = out + jnp.where(gate != 0, gate * g, 0.0)
        return out
    return rhs


def rank_trajectory(table: LawTable, q_pos, qd, t, traj=None, *, sigma, period: float, angles=None, fc_fn=None,
                    shortlist: int = 16, n_boot: int = N_BOOT, seed: int = 0, max_windows: int = 200) -> LawTable:
    """Re-fit the pointwise table's best candidates (and the zero law) to the *positions* by multiple shooting and
    rank them again — for records whose pointwise q̈ is too noisy or biased for the law (see
    :mod:`nnphd.engine.evidence`: windows of ¾ period with free initial states, RK4 at the recorded times).

    The model is the same joint one, q̈ = f_c(q, q̇; α) + g(q, q̇, t; β, θ), with (α, β, θ) started from the
    pointwise fit; held-out error = χ² of contiguous groups of windows predicted by the fit to the others (window
    states re-fitted, linearised at the optimum); uncertainties = window bootstrap (or the model-based error, if
    larger); IC as in :func:`rank_laws` with the position residuals. ``fc_fn(q, v)`` (JAX) must reproduce the ``fc``
    given to :func:`rank_laws`; ``sigma`` (n,) the position noise.
    """
    import jax.numpy as jnp

    from nnphd.engine.evidence import (
        _blocks,
        _pad_windows,
        _schur,
        lm_windows,
        model_residuals_and_jac,
        shooting_windows,
    )

    if table.settings.get("conservative_extra", 0):
        raise ValueError("a law table fitted with conservative_cols can only be ranked pointwise")
    q_pos, qd, t = (np.asarray(a, float) for a in (q_pos, qd, t))
    N, n = q_pos.shape
    traj = np.zeros(N, int) if traj is None else np.asarray(traj)
    angles = tuple(bool(a) for a in (np.zeros(n, bool) if angles is None else angles))
    segs = _segments(traj)
    wins = shooting_windows(segs, t, period)
    if len(wins) > max_windows:
        keep = np.unique(np.linspace(0, len(wins) - 1, max_windows).round().astype(int))
        wins = [wins[i] for i in keep]
    if len(wins) < 6:
        return table
    spread = np.array([np.ptp(q_pos[:, j]) for j in range(n)])
    sig = np.maximum(np.asarray(sigma, float), 1e-3 * np.maximum(spread, 1e-12))
    tw, qw, mask, s0 = _pad_windows(wins, t, q_pos, (q_pos, qd))
    t0w = tw[:, 0].copy()
    tw = tw - tw[:, :1]
    dtmax = float(np.max(np.diff(tw, axis=1)))
    vmax = float(np.max(np.abs(qd)) / max(np.min(spread), 1e-12))
    nsub = int(min(8, max(1, math.ceil(dtmax * max(vmax, 2 * math.pi / period if np.isfinite(period) else 0) / 0.3))))
    args = (jnp.asarray(tw), jnp.asarray(t0w), jnp.asarray(qw), jnp.asarray(mask), jnp.asarray(1.0 / sig))
    W = len(wins)
    G = min(W, 10)
    groups = np.array_split(np.arange(W), G)
    n_res = int(mask.sum()) * n
    Kc = table.settings["conservative_columns"]
    zero = next(r for r in table.rows if r.key == "none")
    cands = [r for r in table.rows if r.key != "none"][:shortlist]  # the table holds one row per family
    alpha0 = table.settings["_alpha"]
    fams = [r.family for r in cands]
    slots, off = [], Kc  # where each family's (β, θ, gate) sit in the universal θ
    for f in fams:
        K, m = len(f.coef_names), len(f.nl_names)
        slots.append((off, K, m))
        off += K + m + 1
    P_glob = off
    P_dir = Kc + max([K + m for _, K, m in slots], default=0)
    rhs = _universal_rhs(fams, Kc, angles, fc_fn, table.settings["_center"],
                         table.settings.get("library", True))
    nl_defaults = np.zeros(P_glob)
    for f, (o, K, m) in zip(fams, slots):
        if m:
            lo, hi = (np.asarray(x, float) for x in f.nl_bounds)
            nl_defaults[o + K:o + K + m] = np.clip(1.0, lo, np.where(np.isfinite(hi), hi, 1.0))
    results = []
    for ci, row in enumerate([zero, *cands]):
        fam = row.family
        base = nl_defaults.copy()
        idx = list(range(Kc))
        u0 = list(alpha0[id(row)])
        if fam is not None:
            o, K, m = slots[ci - 1]
            base[o + K + m] = 1.0
            idx += list(range(o, o + K + m))
            u0 += list(row.beta) + list(row.theta)
            base[o:o + K + m] = 0.0
        D = np.zeros((P_dir, P_glob))
        D[np.arange(len(idx)), idx] = 1.0
        u0 = np.concatenate([u0, np.zeros(P_dir - len(idx))])
        aux = (jnp.asarray(base), jnp.asarray(D))

        def resjac(s_, u_, aux=aux):
            return model_residuals_and_jac(s_, u_, aux, *args, rhs=rhs, nsub=nsub)

        free = np.zeros(P_dir, bool)
        free[:len(idx)] = True
        try:
            s, th, r, jac, chi2 = lm_windows(resjac, s0, u0, free, iters=15)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            continue
        if not np.isfinite(chi2):
            continue
        if fam is not None and fam.nl_names:  # LM knows no bounds: out of them, fit again with θ clipped and fixed
            lo, hi = (np.asarray(x, float) for x in fam.nl_bounds)
            K = len(fam.coef_names)
            nl = th[Kc + K:len(idx)]
            if np.any(nl < lo) or np.any(nl > hi):
                th1 = th.copy()
                th1[Kc + K:len(idx)] = np.clip(nl, lo, hi)
                free[Kc + K:len(idx)] = False
                s, th, r, jac, chi2 = lm_windows(resjac, s, th1, free, iters=15)
                if not np.isfinite(chi2):
                    continue
        th = th[:len(idx)]
        free = free[:len(idx)]
        jac = jac[:2 * n + len(idx)]
        AtA, AtB, BtB, Atr, Btr, rr = _blocks(r, jac, 2 * n)
        S, g, _XB, Xr = _schur(AtA, AtB, BtB, Atr, Btr, 0.0, free)
        c_loc = rr - np.einsum("wi,wi->w", Atr, Xr)  # χ² per window with its states re-optimised
        Stot, gtot = S.sum(0), g.sum(0)
        cv = 0.0
        for grp in groups:
            Sg, gg = S[grp].sum(0), g[grp].sum(0)
            d = -_solve(_ridge(Stot - Sg), gtot - gg)
            cv += float(c_loc[grp].sum() + 2 * gg @ d + d @ Sg @ d)
        fi = np.flatnonzero(free)  # S, g are over the free parameters
        rng = np.random.default_rng(seed)
        reps = []
        for _ in range(n_boot if fam is not None else 0):
            idx = rng.integers(0, W, W)
            rep = th.copy()
            rep[fi] -= _solve(_ridge(S[idx].sum(0)), g[idx].sum(0))
            reps.append(rep)
        law_idx = np.arange(Kc, len(th))
        se_b = np.asarray(reps)[:, law_idx].std(axis=0) if reps else np.zeros(len(law_idx))
        s2 = chi2 / max(n_res - W * 2 * n - len(fi), 1)
        var = np.zeros(len(th))
        var[fi] = np.diag(s2 * np.linalg.pinv(_ridge(Stot)))
        se_m = np.sqrt(np.maximum(var[law_idx], 0.0))
        R = r.reshape(W, -1)
        rho = float(np.sum(R[:, n:] * R[:, :-n]) / max(np.sum(R * R), 1e-300))
        results.append((row, th, max(cv, 1e-300), np.maximum(se_b, se_m), rho, _overdispersion(se_b, se_m, th[Kc:])))
    if len(results) < 2 or results[0][0].key != "none":
        return table
    rho = float(np.clip(np.median([x[4] for x in results]), 0.0, 0.95))
    c_hat = _c_hat([x[5] for x in results], [x[2] for x in results])
    tau = (1 + rho) / (1 - rho) * c_hat
    n_eff = n_res / tau
    rows = []
    for row, th, cv, se, _, _ in results:
        fam = row.family
        if fam is None:
            new = _zero_row(table.settings["names"], cv / n_res, N, "trajectory")
        else:
            K = len(fam.coef_names)
            new = _law_row(fam, th[Kc:Kc + K], th[Kc + K:], se, table.settings["names"], cv / n_res, "trajectory")
            new.fn = new.predict(q_pos, qd, t)
        new.ic = n_eff * math.log(cv / n_res) + row.k * math.log(max(n_eff, 2.0))
        rows.append(new)
    _relative_to_zero(rows, table.settings["_y_rms"])
    return _select(rows, n_eff, tau, f"{G} held-out groups of shooting windows ({W} windows)",
                   {**table.settings, "method": "trajectory", "windows": W, "substeps": nsub,
                    "pointwise_candidates": [r.to_dict() for r in table.rows]})


C_HAT_MAX = 20.0


def _overdispersion(se_boot, se_model, values=None) -> float | None:
    """Mean (bootstrap se / model se)² over a candidate's law parameters, at most C_HAT_MAX (None without any, or
    when the model error is at rounding level: exact data carry no information about overdispersion)."""
    scale = np.abs(values) if values is not None else np.zeros_like(se_model)
    ok = np.isfinite(se_boot) & np.isfinite(se_model) & (se_model > 1e-9 * scale) & (se_model > 0)
    return float(min(C_HAT_MAX, np.mean((se_boot[ok] / se_model[ok]) ** 2))) if ok.any() else None


def _c_hat(ratios, errors) -> float:
    """Overdispersion ĉ ≥ 1 (as in QAIC, from the best-fitting model): (bootstrap / model variance) of the
    candidate with the lowest held-out error — when the resampled fits scatter more than the residuals' own scatter
    implies (misfit that varies along the record), the information in the data is smaller than its row count says,
    and every IC difference shrinks by ĉ."""
    ok = [(e, x) for x, e in zip(ratios, errors) if x is not None and np.isfinite(x)]
    return float(max(1.0, min(ok)[1])) if ok else 1.0


def _at_bound(fam: Family, theta) -> bool:
    """A nonlinear parameter on (or past) a finite edge of its range: the optimum is not interior, the law is not
    identified (e.g. a power law pushed to m = 8 to fit a few of the fastest rows)."""
    if not fam.nl_names or theta is None or len(theta) == 0:
        return False
    lo, hi = (np.asarray(x, float) for x in fam.nl_bounds)
    th = np.asarray(theta, float)
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    tol = 1e-6 * np.maximum(span, 1e-12)
    return bool(np.any((np.isfinite(lo) & (th <= lo + tol)) | (np.isfinite(hi) & (th >= hi - tol))))


def _significance(rows: list[LawFit]) -> None:
    for r in rows:
        if r.family is not None and r.fn_rel < 1e-9:  # a law at the rounding level of the data is no law
            r.significant = False
            continue
        if r.family is not None and _at_bound(r.family, r.theta):
            r.significant = False
            continue
        if r.family is not None and r.family.per_term:
            z = [abs(r.params[p]) / r.stderr[p] if r.stderr[p] > 0 else np.inf for p in r.family.coef_names]
            r.significant = bool(min(z) >= Z_TERM) if z else True


def _law_row(fam: Family, beta, theta, se, names, heldout_mse: float, method: str) -> LawFit:
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
    return LawFit(fam.key, fam.title, fam.k, {p: float(x) for p, x in zip(pn, vals)},
                  {p: float(x) for p, x in zip(pn, se)}, {f"{c}_ddot": str(e) for c, e in zip(names, exprs)},
                  {f"{c}_ddot": sp.latex(e) for c, e in zip(names, exprs)}, heldout_mse, 1.0, 0.0, 0.0, 0.0,
                  fam.terms, method=method, family=fam, theta=np.asarray(theta, float), beta=np.asarray(beta, float))


def _zero_row(names, heldout_mse: float, N: int, method: str) -> LawFit:
    zero = {f"{c}_ddot": "0" for c in names}
    return LawFit("none", "no law (conservative model alone)", 0, {}, {}, zero, dict(zero), heldout_mse, 1.0, 0.0,
                  0.0, 0.0, (), method=method, fn=np.zeros((N, len(names))))


def _relative_to_zero(rows: list[LawFit], y_rms: float) -> None:
    """Held-out ratio and ΔIC against the zero law (rows[0]), and the law's size relative to q̈."""
    z = rows[0]
    for r in rows:
        r.heldout_ratio = float(math.sqrt(r.heldout_mse / z.heldout_mse)) if z.heldout_mse > 0 else 1.0
        r.delta_ic = r.ic - z.ic
        r.fn_rel = float(np.sqrt(np.mean(r.fn**2))) / (y_rms or 1.0)


def _select(rows: list[LawFit], n_eff, tau, folds, settings) -> LawTable:
    _significance(rows)
    order = {id(r): i for i, r in enumerate(rows)}
    rows = sorted(rows, key=lambda r: r.ic)
    eligible = [r for r in rows if r.significant]
    best = eligible[0]
    tied = [r for r in eligible if r.ic <= best.ic + IC_TIE]
    win = min(tied, key=lambda r: (r.k, r.key == "sparse", order[id(r)]))
    rows.remove(win)
    rows.insert(0, win)
    if win.key == "none":
        nxt = rows[1] if len(rows) > 1 else None
        reason = ("no candidate beats zero: " + (
            f"the best, {nxt.title}, changes the held-out error by {100 * (nxt.heldout_ratio - 1):+.2f}% and its "
            f"{nxt.k} parameter(s) cost more (ΔIC = {nxt.delta_ic:+.1f})" if nxt else "no candidate could be fitted"))
        law = None
    else:
        reason = (f"{win.title} lowers the held-out error by {100 * (1 - win.heldout_ratio):.2f}% with {win.k} "
                  f"parameter(s) (ΔIC = {win.delta_ic:.1f} against no law)")
        if len(tied) > 1:
            reason += f"; {len(tied) - 1} other candidate(s) within ΔIC {IC_TIE:g} — the simplest is kept"
        skipped = [r for r in rows if not r.significant and r.ic < win.ic]
        if skipped:
            reason += (f"; {len(skipped)} candidate(s) with a lower IC have a term within {Z_TERM:g} standard errors "
                       f"of zero or a parameter at the edge of its range and are not eligible "
                       f"({', '.join(r.key for r in skipped)})")
        law = win
    return LawTable(rows, law, reason, float(n_eff), float(tau), folds, settings)
