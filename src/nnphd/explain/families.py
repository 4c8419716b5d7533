r"""The candidate laws g(q, q̇, t; β, θ) of the non-conservative force, each a :class:`Family`: linear in its
coefficients β given a few nonlinear parameters θ (an exponent m, a drive frequency ω).

Every candidate is odd under time reversal (it does work) or explicitly time-dependent. Built-in families
(:func:`families`): linear friction (isotropic, diagonal, full Γ), quadratic drag −c|q̇|q̇, Coulomb −μ sign(q̇)
(smoothed: q̇/√(q̇² + ε²), ε = 2 % of the rms speed), the power law −k(|q̇|²)^m q̇ with m free, Rayleigh (a + c q̇²)q̇,
van der Pol (a + b q²)q̇ and both together, a drive A cos(ωt + φ) with ω started from the peaks of the conservative
residual's Lomb–Scargle spectrum. Besides them: the perturber on a circular orbit (:func:`perturber_family`, opt-in),
a sparse polynomial (odd in q̇, degree ≤ 3, :func:`sparse_family` on a support thresholded jointly with f_c by
:func:`nnphd.explain.laws.rank_laws`), and user laws written as SymPy strings (:func:`parse_law`).
:func:`family_from_spec` rebuilds any of them from its JSON-ready :attr:`Family.spec`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import sympy as sp

__all__ = ["Family", "families", "family_from_spec", "parse_law", "perturber_family", "sparse_family"]

COULOMB_EPS = 0.02  # smoothing of sign(q̇), as a fraction of the rms speed
SPARSE_DEGREE = 3
DIGITS = 4


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
    v_rms = np.asarray(v_rms, float)
    eps = np.where(v_rms > 0, COULOMB_EPS * v_rms, 1.0)  # relative to the speeds: units must not matter
    v_all = float(np.sqrt(np.sum(np.square(v_rms))))
    eps_all = COULOMB_EPS * v_all if v_all > 0 else 1.0
    nm = list(names)
    out: list[Family] = []
    one = n == 1

    def add(*a, **kw):
        out.append(Family(*a, **kw))

    # linear friction
    if not one:
        add(
            "linear",
            "linear friction −γ q̇ (isotropic)",
            ("gamma",),
            lambda xp, th, q, v, t: -v[:, :, None],
            lambda th, Q, V, T: [[-V[i]] for i in range(n)],
            terms=("q̇",),
        )
    add(
        "linear-diag" if not one else "linear",
        "linear friction −γ_i q̇_i" if not one else "linear friction −γ q̇",
        tuple(f"gamma_{c}" for c in nm) if not one else ("gamma",),
        lambda xp, th, q, v, t: _eye_cols(xp, -v),
        lambda th, Q, V, T: _sym_diag(n, [-x for x in V]),
        terms=("q̇_i",) if not one else ("q̇",),
    )
    if not one:
        add(
            "linear-full",
            "linear friction −Γ q̇ (full Γ)",
            tuple(f"Gamma_{a}{b}" for a in nm for b in nm),
            lambda xp, th, q, v, t: (
                -(v[:, None, None, :] * xp.eye(n, dtype=v.dtype)[None, :, :, None]).reshape(v.shape[0], n, n * n)
            ),
            lambda th, Q, V, T: [
                [(-V[j] if a == i else sp.Integer(0)) for a in range(n) for j in range(n)] for i in range(n)
            ],
            terms=("Γq̇",),
        )
    # quadratic drag
    if not one:
        add(
            "quadratic",
            "quadratic drag −c |q̇| q̇",
            ("c",),
            lambda xp, th, q, v, t: -(xp.sqrt(xp.sum(v * v, axis=1))[:, None] * v)[:, :, None],
            lambda th, Q, V, T: [[-sp.sqrt(sum(x**2 for x in V)) * V[i]] for i in range(n)],
            terms=("|q̇|q̇",),
        )
    add(
        "quadratic-diag" if not one else "quadratic",
        "quadratic drag −c_i |q̇_i| q̇_i" if not one else "quadratic drag −c |q̇| q̇",
        tuple(f"c_{c}" for c in nm) if not one else ("c",),
        lambda xp, th, q, v, t: _eye_cols(xp, -xp.abs(v) * v),
        lambda th, Q, V, T: _sym_diag(n, [-sp.Abs(x) * x for x in V]),
        terms=("|q̇_i|q̇_i",) if not one else ("|q̇|q̇",),
    )
    # Coulomb (dry) friction, smoothed sign
    if not one:
        add(
            "coulomb",
            "Coulomb friction −μ q̇/|q̇|",
            ("mu",),
            lambda xp, th, q, v, t: -(v / xp.sqrt(xp.sum(v * v, axis=1) + eps_all**2)[:, None])[:, :, None],
            lambda th, Q, V, T: [[-V[i] / sp.sqrt(sum(x**2 for x in V))] for i in range(n)],
            terms=("q̇/|q̇|",),
        )
    add(
        "coulomb-diag" if not one else "coulomb",
        "Coulomb friction −μ_i sign(q̇_i)" if not one else "Coulomb friction −μ sign(q̇)",
        tuple(f"mu_{c}" for c in nm) if not one else ("mu",),
        lambda xp, th, q, v, t: _eye_cols(xp, -v / xp.sqrt(v * v + xp.asarray(eps, v.dtype) ** 2)),
        lambda th, Q, V, T: _sym_diag(n, [-sp.sign(x) for x in V]),
        terms=("sign(q̇_i)",) if not one else ("sign(q̇)",),
    )

    # power law with m free
    def _pow_basis(xp, th, q, v, t):
        s = xp.sum(v * v, axis=1)
        sm = xp.where(s > 0, xp.where(s > 0, s, 1.0) ** th[0], 0.0)
        return -(sm[:, None] * v)[:, :, None]

    add(
        "power",
        "power-law drag −k (|q̇|²)^m q̇",
        ("k",),
        _pow_basis,
        lambda th, Q, V, T: [[-((sum(x**2 for x in V)) ** sp.Float(th[0], DIGITS)) * V[i]] for i in range(n)],
        nl_names=("m",),
        nl_starts=lambda ctx: [[0.25], [1.0], [2.0], [4.0]],
        nl_bounds=([0.0], [8.0]),
        terms=("(|q̇|²)^m q̇",),
        per_term=False,
    )
    # Rayleigh / van der Pol, per coordinate
    sfx = (lambda c: f"_{c}") if not one else (lambda c: "")
    add(
        "rayleigh",
        "Rayleigh (a + c q̇²) q̇",
        tuple(f"{p}{sfx(c)}" for p in ("a", "c") for c in nm),
        lambda xp, th, q, v, t: xp.concatenate([_eye_cols(xp, v), _eye_cols(xp, v**3)], axis=2),
        lambda th, Q, V, T: [r1 + r2 for r1, r2 in zip(_sym_diag(n, V), _sym_diag(n, [x**3 for x in V]))],
        terms=("q̇", "q̇³"),
    )
    add(
        "vanderpol",
        "van der Pol (a + b q²) q̇",
        tuple(f"{p}{sfx(c)}" for p in ("a", "b") for c in nm),
        lambda xp, th, q, v, t: xp.concatenate([_eye_cols(xp, v), _eye_cols(xp, q * q * v)], axis=2),
        lambda th, Q, V, T: [
            r1 + r2 for r1, r2 in zip(_sym_diag(n, V), _sym_diag(n, [x**2 * y for x, y in zip(Q, V)]))
        ],
        terms=("q̇", "q²q̇"),
    )
    add(
        "rayleigh-vdp",
        "Rayleigh–van der Pol (a + b q² + c q̇²) q̇",
        tuple(f"{p}{sfx(c)}" for p in ("a", "b", "c") for c in nm),
        lambda xp, th, q, v, t: xp.concatenate(
            [_eye_cols(xp, v), _eye_cols(xp, q * q * v), _eye_cols(xp, v**3)], axis=2
        ),
        lambda th, Q, V, T: [
            r1 + r2 + r3
            for r1, r2, r3 in zip(
                _sym_diag(n, V), _sym_diag(n, [x**2 * y for x, y in zip(Q, V)]), _sym_diag(n, [x**3 for x in V])
            )
        ],
        terms=("q̇", "q²q̇", "q̇³"),
    )

    # drive of unknown frequency
    def _drive_basis(xp, th, q, v, t):
        c, s = xp.cos(th[0] * t), xp.sin(th[0] * t)
        ones = xp.ones_like(q)
        return xp.concatenate([_eye_cols(xp, c[:, None] * ones), _eye_cols(xp, s[:, None] * ones)], axis=2)

    add(
        "drive",
        "drive A cos(ω t + φ)",
        tuple(f"{p}{sfx(c)}" for p in ("A_cos", "A_sin") for c in nm),
        _drive_basis,
        lambda th, Q, V, T: [
            r1 + r2
            for r1, r2 in zip(
                _sym_diag(n, [sp.cos(sp.Float(th[0], 6) * T)] * n), _sym_diag(n, [sp.sin(sp.Float(th[0], 6) * T)] * n)
            )
        ],
        nl_names=("omega",),
        nl_starts=lambda ctx: [[w] for w in ctx["drive_omegas"]],
        nl_bounds=([1e-9], [np.inf]),
        terms=("cos(ωt)",),
        per_term=False,
    )
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

    return Family(
        "perturber",
        "perturber GM (r_p(t) − q)/|r_p(t) − q|³ on a circular orbit",
        ("GM",),
        basis,
        symbols,
        nl_names=("R", "omega", "phi"),
        nl_starts=starts,
        nl_bounds=([1e-9, -np.inf, -np.inf], [np.inf, np.inf, np.inf]),
        terms=("(r_p(t) − q)/|r_p − q|³",),
        per_term=False,
        spec={"kind": "perturber"},
    )


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
    return Family(
        "sparse",
        "sparse polynomial (odd in q̇, degree ≤ 3)",
        coef,
        basis,
        symbols,
        terms=tuple(sorted({str(msym[m]) for _, m in idx})),
        spec={"kind": "sparse", "support": np.asarray(support, bool).tolist()},
    )


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
                raise ValueError(
                    f"law {text!r}: {head.strip()!r} is not a coordinate (expected one of {', '.join(coords)})"
                )
            comps[coords.index(name)] = body
        elif len(coords) == 1 and not comps:
            comps[0] = p
        else:
            raise ValueError(
                f"law {text!r}: with {len(coords)} coordinates name the component of each term, "
                f"e.g. '{coords[0]}: -c*{coords[0]}_dot; {coords[1]}: -c*{coords[1]}_dot'"
            )
    Q = [sp.Symbol(c) for c in coords]
    V = [sp.Symbol(f"{c}_dot") for c in coords]
    T = sp.Symbol("t")
    known = {s.name: s for s in (*Q, *V, T)}
    exprs = [sp.Integer(0)] * len(coords)
    for i, body in comps.items():
        try:
            e = sp.sympify(body, locals={**known, "abs": sp.Abs, "sign": sp.sign})
        except (sp.SympifyError, SyntaxError, TypeError) as err:
            raise ValueError(
                f"law {text!r}: cannot read {body.strip()!r} as a formula ({err.__class__.__name__})"
            ) from None
        if not isinstance(e, sp.Expr):
            raise ValueError(f"law {text!r}: {body.strip()!r} is not a formula")  # noqa: TRY004 (a bad --law is bad input: exit 2)
        exprs[i] = e
    params = sorted({s for e in exprs for s in e.free_symbols} - set(known.values()), key=lambda s: s.name)
    if not params:
        raise ValueError(
            f"law {text!r} has no free parameter to fit (symbols other than the coordinates, "
            f"their _dot velocities and t are parameters)"
        )
    bad = [p.name for p in params if p.name.endswith("_dot")]
    if bad:
        raise ValueError(
            f"law {text!r}: {bad[0]!r} is not the velocity of a coordinate (coordinates: {', '.join(coords)})"
        )
    lin: list = []  # parameters the law is jointly linear in (their coefficients may hold the others)
    for p in params:
        if all(
            sp.simplify(sp.diff(e, p, 2)) == 0 and all(sp.simplify(sp.diff(e, p, p2)) == 0 for p2 in lin) for e in exprs
        ):
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
        sub = {
            **{a: b for a, b in zip(Q, Qs)},
            **{a: b for a, b in zip(V, Vs)},
            T: Ts,
            **{p: sp.Float(x, DIGITS) for p, x in zip(nl, th)},
        }
        return [[b.xreplace(sub) for b in row] for row in base]

    fam = Family(
        "user",
        f"user law {text}",
        tuple(p.name for p in lin),
        basis,
        symbols,
        nl_names=tuple(p.name for p in nl),
        nl_starts=(lambda ctx: [[1.0] * len(nl)]) if nl else None,
        nl_bounds=([-np.inf] * len(nl), [np.inf] * len(nl)),
        terms=(text,),
        fixed=fixed,
        per_term=False,
        spec={"kind": "user", "text": text},
    )
    if not lin:
        raise ValueError(
            f"law {text!r}: it must be linear in at least one parameter (a coefficient in front of a "
            "term), e.g. 'c*x_dot**m'"
        )
    _ = fam.symbols([1.0] * len(nl), Q, V, T)  # fail early on a formula SymPy cannot rebuild
    return fam
